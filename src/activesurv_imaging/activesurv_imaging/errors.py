"""Exceptions of the imaging package. Core code raises these; nodes catch and report them.

Camera-model, mount and geometry errors are the shared core's (``activesurv_common.errors``);
they are re-exported here so that ``except CalibrationError`` reads the same in imaging code.
"""

from __future__ import annotations

from activesurv_common.errors import (
    CalibrationError,
    CommonError,
    GeometryError,
    SensorModelError,
)

__all__ = [
    'CalibrationError',
    'CirclePoseError',
    'CommonError',
    'EllipseFitError',
    'GeometryError',
    'ImagingError',
    'SensorModelError',
    'VisionErrors',
]


class ImagingError(Exception):
    """Base class of all activesurv_imaging errors."""


class EllipseFitError(ImagingError, ValueError):
    """The points do not determine an ellipse (too few, degenerate, or a non-ellipse conic)."""


class CirclePoseError(ImagingError, ValueError):
    """No circle pose follows from the ellipse (degenerate cone, marker behind the camera)."""


# What a vision step may raise on bad input: catch these together where a node reports them.
VisionErrors = (ImagingError, CommonError)
