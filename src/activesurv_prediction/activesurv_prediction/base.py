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

    @property
    def rejections(self) -> int: ...

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


class OutlierGate:
    """The chi-square gate both predictors put on a fix's innovation.

    A fix whose squared Mahalanobis distance exceeds ``gate`` (0: no gate) is rejected and does
    not touch the state. After ``max_rejections`` in a row the object has not jumped but
    manoeuvred: the rejected fixes agree with each other, and the filter restarts from them
    (:meth:`restart_velocity`).

    Raises:
        PredictionError: for a negative or non-finite gate or ``max_rejections`` < 1.
    """

    def __init__(self, gate: float, max_rejections: int) -> None:
        if not (math.isfinite(gate) and gate >= 0.0):
            raise PredictionError(f'gate must be finite and >= 0, got {gate}')
        if max_rejections < 1:
            raise PredictionError(f'max_rejections must be >= 1, got {max_rejections}')
        self.gate = float(gate)
        self.max_rejections = int(max_rejections)
        self.rejections = 0
        self.consecutive = 0
        self._rejected: list[tuple[float, Array]] = []

    def judge(self, t: float, z: Array, d2: float) -> str:
        """``accept``, ``reject`` or ``restart`` for fix ``z`` at ``t`` with distance ``d2``."""
        if not (self.gate > 0.0 and d2 > self.gate):
            self.clear()
            return 'accept'
        self.rejections += 1
        self.consecutive += 1
        self._rejected.append((t, z))
        return 'restart' if self.consecutive >= self.max_rejections else 'reject'

    def restart_velocity(self, measurement_std: float) -> tuple[Array | None, float | None]:
        """The velocity the rejected fixes show and its std (None: a single fix)."""
        (t0, z0), (t1, z1) = self._rejected[0], self._rejected[-1]
        span = t1 - t0
        if span <= 0.0:
            return None, None
        return (z1 - z0) / span, 2.0 * measurement_std / span

    def clear(self) -> None:
        self.consecutive = 0
        self._rejected.clear()
