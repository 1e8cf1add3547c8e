"""Exceptions of the bringup package."""

from __future__ import annotations


class BringupError(Exception):
    """Base class of all activesurv_bringup errors."""


class NodeDiedError(BringupError):
    """A required node process exited while the run was going."""


class ConfigError(BringupError, ValueError):
    """A configuration file or command-line value is invalid."""


class BagError(BringupError):
    """A bag cannot be written or read (missing, truncated, corrupt)."""
