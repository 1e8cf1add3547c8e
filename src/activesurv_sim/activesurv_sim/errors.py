"""Exceptions of the simulator."""

from __future__ import annotations


class SimError(Exception):
    """Base class of all activesurv_sim errors."""


class RenderError(SimError, ValueError):
    """A scene or render request is malformed."""
