"""Exceptions of the hardware package."""

from __future__ import annotations


class HardwareError(Exception):
    """Base class of all activesurv_hardware errors."""


class HardwareFileError(HardwareError, ValueError):
    """A hardware file that cannot describe a rig (missing keys, bad values, unknown files)."""


class CameraSourceError(HardwareError):
    """A camera that cannot be opened or stopped giving frames."""
