"""Exceptions of the dispatch package."""

from __future__ import annotations


class DispatchError(Exception):
    """Base class of all activesurv_dispatch errors."""


class DispatchConfigError(DispatchError, ValueError):
    """A sensor description, set-up or planner parameter is invalid."""


class VisibilityError(DispatchError, ValueError):
    """A covariance given to the visibility measure is malformed."""
