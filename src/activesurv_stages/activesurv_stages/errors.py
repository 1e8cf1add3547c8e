"""Exceptions of the stages package. Core code raises these; nodes and the CLI report them."""

from __future__ import annotations


class StageError(Exception):
    """Base class of all activesurv_stages errors."""


class LimitError(StageError, ValueError):
    """A goal or limit is invalid or outside the soft travel limits (nothing was sent)."""


class ConfigError(StageError, ValueError):
    """A stage or path configuration is invalid."""


class ProtocolError(StageError):
    """A controller sent something that is not a valid reply (garbage, wrong device)."""


class ControllerRejectedError(StageError):
    """The controller understood the command and refused it (Zaber RJ, GRBL error:N, alarm)."""


class CommunicationError(StageError):
    """The serial line failed: port missing or unplugged, or no reply within the timeout."""
