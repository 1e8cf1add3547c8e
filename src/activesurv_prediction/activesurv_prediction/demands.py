"""Demand instants and the rolling horizon of predicted demand points (pure core).

Demand instants are fixed in advance: either ``first + k * interval`` for k = 0 .. count-1, or
an explicit list. The horizon at time ``now`` is the next ``m`` instants after ``now``, each with
the predicted pose of the surveyed target (the side marker). The xy table only translates, so
the side marker is the top marker plus a rigid offset, and its normal is fixed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_prediction.errors import PredictionError
from activesurv_prediction.predictor import TargetPredictor

Array = NDArray[np.float64]


@dataclass(frozen=True)
class DemandSchedule:
    """The fixed demand instants t_j (s), indexed from 0."""

    times: tuple[float, ...]

    @staticmethod
    def regular(first: float, interval: float, count: int) -> DemandSchedule:
        if not (math.isfinite(first) and math.isfinite(interval) and interval > 0 and count > 0):
            raise PredictionError(
                f'need a finite first instant, interval > 0 and count > 0; got {first}, '
                f'{interval}, {count}'
            )
        return DemandSchedule(tuple(first + k * interval for k in range(count)))

    @staticmethod
    def explicit(times: Sequence[float]) -> DemandSchedule:
        ts = tuple(float(t) for t in times)
        if not ts or not all(math.isfinite(t) for t in ts):
            raise PredictionError('demand instants must be a non-empty list of finite times')
        if any(b <= a for a, b in pairwise(ts)):
            raise PredictionError('demand instants must be strictly increasing')
        return DemandSchedule(ts)

    def upcoming(self, now: float, m: int) -> list[tuple[int, float]]:
        """(index, instant) of the next ``m`` demands strictly after ``now``."""
        return [(j, t) for j, t in enumerate(self.times) if t > now][:m]


@dataclass(frozen=True)
class TargetGeometry:
    """Side marker relative to the top marker (object frame = world axes: no rotation).

    Attributes:
        offset: side-marker centre minus top-marker centre (m).
        normal: unit normal of the side marker in the world.
        z_std: std of the side marker's height (m): the geometry is known, not measured.
        normal_std: std of the normal components.
    """

    offset: Array
    normal: Array
    z_std: float = 0.5e-3
    normal_std: float = 0.01

    @staticmethod
    def create(
        offset: ArrayLike, normal: ArrayLike, z_std: float = 0.5e-3, normal_std: float = 0.01
    ) -> TargetGeometry:
        o = np.asarray(offset, dtype=np.float64).reshape(-1)
        n = np.asarray(normal, dtype=np.float64).reshape(-1)
        if (
            o.shape != (3,)
            or n.shape != (3,)
            or not (np.all(np.isfinite(o)) and np.all(np.isfinite(n)))
        ):
            raise PredictionError('side marker offset and normal need 3 finite numbers each')
        if np.linalg.norm(n) < 1e-9:
            raise PredictionError('side marker normal has zero length')
        return TargetGeometry(o, n / np.linalg.norm(n), z_std, normal_std)


@dataclass(frozen=True)
class DemandPrediction:
    """Predicted side-marker pose at one demand instant.

    Attributes:
        index, instant: the demand.
        position: (3,) predicted marker centre (world).
        normal: (3,) marker normal.
        covariance: 6x6 over (x, y, z, rot_x, rot_y, rot_z).
    """

    index: int
    instant: float
    position: Array
    normal: Array
    covariance: Array


def predict_demands(
    predictor: TargetPredictor,
    schedule: DemandSchedule,
    geometry: TargetGeometry,
    top_height: float,
    now: float,
    m: int,
) -> list[DemandPrediction]:
    """The rolling horizon: predicted target poses at the next ``m`` demand instants."""
    if predictor.last_time is None:
        return []
    out = []
    for j, t in schedule.upcoming(max(now, predictor.last_time), m):
        mean, cov = predictor.predict(t)
        pos = np.array([mean[0], mean[1], top_height]) + geometry.offset
        C = np.zeros((6, 6))
        C[:2, :2] = cov
        C[2, 2] = geometry.z_std**2
        C[3:, 3:] = np.eye(3) * geometry.normal_std**2
        out.append(DemandPrediction(j, t, pos, geometry.normal.copy(), C))
    return out
