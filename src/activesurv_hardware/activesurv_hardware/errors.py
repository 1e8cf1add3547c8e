"""Exceptions of the hardware package."""

from __future__ import annotations


class HardwareError(Exception):
    """Base class of all activesurv_hardware errors."""


class HardwareFileError(HardwareError, ValueError):
    """A hardware file that cannot describe a rig (missing keys, bad values, unknown files).

    Attributes:
        problems: every mistake found, one line each naming its key path.
    """

    def __init__(self, message: str, problems: list[str] | None = None) -> None:
        super().__init__(message)
        self.problems = list(problems) if problems is not None else [message]


class CameraSourceError(HardwareError):
    """A camera that cannot be opened or stopped giving frames."""
