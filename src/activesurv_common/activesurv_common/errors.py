"""Exceptions of the shared core: geometry, camera and mount models, sensor model, eq. 2."""

from __future__ import annotations


class CommonError(Exception):
    """Base class of all activesurv_common errors."""


class GeometryError(CommonError, ValueError):
    """A vector, rotation or transform is malformed (wrong shape, not finite, zero length)."""


class CalibrationError(CommonError, ValueError):
    """A camera model, mount or calibration value is malformed or cannot be solved."""


class SensorModelError(CommonError, ValueError):
    """A sensor model file or its response surfaces are malformed."""


class InformationError(CommonError, ValueError):
    """Covariances handed to information fusion (eq. 2) are malformed."""


class ImageFormatError(CommonError, ValueError):
    """An image message cannot be read (unsupported encoding, buffer and header disagree)."""
