"""Exceptions of the launch package."""

from __future__ import annotations


class LaunchError(Exception):
    """Base class of all activesurv_launch errors."""


class NodeDiedError(LaunchError):
    """A required node process exited while the run was going."""
