"""Exceptions of the prediction package."""

from __future__ import annotations


class PredictionError(ValueError):
    """Invalid input to the predictor (non-finite values, times out of order, no track yet)."""
