"""What every predictor shares: the verdict on one fix, input checks and the interface the
tracker, the demand horizon and the benchmarks program against (pure core)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_prediction.errors import PredictionError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class UpdateResult:
    """What one fix did.

    Attributes:
        accepted: the fix updated the state (False: gated out as an outlier).
        mahalanobis2: squared Mahalanobis distance of the innovation (NaN on the first fix).
        restarted: this fix restarted the filter after a run of rejections.
    """

    accepted: bool
    mahalanobis2: float
    restarted: bool = False


class Predictor(Protocol):
    """A planar position predictor fed with overhead fixes."""

    last_time: float | None
    updates: int
    rejections: int

    def reset(self) -> None: ...

    def update(self, t: float, xy: ArrayLike) -> UpdateResult: ...

    def predict(self, t: float) -> tuple[Array, Array]: ...

    def predict_mean(self, t: float) -> Array: ...

    def predict_many(self, times: Sequence[float]) -> list[tuple[Array, Array]]: ...

    @property
    def mode_names(self) -> tuple[str, ...]: ...

    @property
    def mode_probabilities(self) -> Array: ...


def check_time(t: float) -> float:
    """``t`` as a float, or a :class:`PredictionError` (a ValueError) if it is not finite."""
    if not isinstance(t, (int, float, np.floating)) or not math.isfinite(float(t)):
        raise PredictionError(f'time must be a finite number of seconds, got {t!r}')
    return float(t)


def check_fix(xy: ArrayLike) -> Array:
    """A fix as a (2,) array, or a :class:`PredictionError` if it is not two finite numbers."""
    z = np.asarray(xy, dtype=np.float64).reshape(-1)
    if z.shape != (2,) or not np.all(np.isfinite(z)):
        raise PredictionError(f'xy must be two finite numbers (metres), got {xy!r}')
    return z


def check_positive(**values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0.0):
            raise PredictionError(f'{name} must be finite and > 0, got {value}')
