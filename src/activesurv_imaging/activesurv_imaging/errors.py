"""Exceptions of the imaging package. Core code raises these; nodes catch and report them."""

from __future__ import annotations


class ImagingError(Exception):
    """Base class of all activesurv_imaging errors."""


class GeometryError(ImagingError, ValueError):
    """A geometric quantity is malformed (wrong shape, non-finite, zero length)."""
