"""Exceptions of the fusion package. Core code raises these; the node catches and reports them."""

from __future__ import annotations


class FusionError(Exception):
    """Base class of all activesurv_fusion errors."""


class NoConsensusError(FusionError):
    """No point is covered by at least ``k - k_f`` abstract sensors: the readings disagree."""


class InvalidReadingError(FusionError, ValueError):
    """A reading or interval is malformed (NaN, lower > upper, bad covariance, empty input)."""
