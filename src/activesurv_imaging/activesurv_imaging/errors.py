"""Exceptions of the imaging package. Core code raises these; nodes catch and report them."""

from __future__ import annotations


class ImagingError(Exception):
    """Base class of all activesurv_imaging errors."""


class GeometryError(ImagingError, ValueError):
    """A geometric quantity is malformed (wrong shape, non-finite, zero length)."""


class CalibrationError(ImagingError, ValueError):
    """A camera calibration (intrinsics, extrinsics, mount) is missing or malformed."""


class RenderError(ImagingError, ValueError):
    """A simulated scene or rendering setting is invalid."""


class EllipseFitError(ImagingError, ValueError):
    """The points do not determine an ellipse (too few, degenerate, or a non-ellipse conic)."""


class CirclePoseError(ImagingError, ValueError):
    """No circle pose follows from the ellipse (degenerate cone, marker behind the camera)."""


class SensorModelError(ImagingError, ValueError):
    """A sensor model file or query is invalid."""
