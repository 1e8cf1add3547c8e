"""Exceptions of the bringup package (and those of the packages it drives, re-exported)."""

from __future__ import annotations

from pathlib import Path

from activesurv_hardware.errors import HardwareError
from activesurv_launch.errors import LaunchError as LaunchError
from activesurv_launch.errors import NodeDiedError as NodeDiedError
from activesurv_recording.errors import BagError as BagError
from activesurv_recording.errors import RecordingError as RecordingError


class BringupError(Exception):
    """Base class of all activesurv_bringup errors."""


class ConfigError(BringupError, ValueError):
    """A configuration file or command-line value is invalid."""


class HardwareCheckError(ConfigError):
    """A hardware file with mistakes: :attr:`problems` holds one line per mistake."""

    def __init__(self, path: Path | str, problems: list[str]) -> None:
        n = len(problems)
        if n == 1:  # one line, as every refused argument is
            super().__init__(f'hardware file {path}: {problems[0].removeprefix("(file): ")}')
        else:
            super().__init__(f'hardware file {path}: {n} mistakes:\n  ' + '\n  '.join(problems))
        self.problems = problems


# What a command reports as a one-line error rather than a traceback.
USER_ERRORS: tuple[type[Exception], ...] = (
    BringupError,
    LaunchError,
    RecordingError,
    HardwareError,
)
