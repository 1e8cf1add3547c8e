"""Exceptions of the recording package."""

from __future__ import annotations


class RecordingError(Exception):
    """Base class of all activesurv_recording errors."""


class BagError(RecordingError):
    """A bag cannot be written or read (missing, truncated, corrupt)."""
