"""Fusion of per-camera marker poses in the world frame (paper Section III-D-2).

Each camera reading is the marker centre (x, y, z) and unit normal (n_x, n_y, n_z) with a 6x6
covariance R over those six variables from the sensor model. Optimal Region fuses each variable
on its own, with the abstract-sensor half-width ``delta = z * sigma`` from R's diagonal; the fused
normal is renormalised. A camera is judged faulty when, for any variable, it covers no probable
region; the fused covariance is the paper's ``P = (sum R_i^-1)^-1`` over the cameras used.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.information import information_fusion
from activesurv_fusion.errors import InvalidReadingError, NoConsensusError
from activesurv_fusion.optimal_region import (
    OptimalRegion,
    default_max_faulty,
    optimal_region_unchecked,
)

VARIABLES = ('x', 'y', 'z', 'n_x', 'n_y', 'n_z')


@dataclass(frozen=True)
class PoseReading:
    """One camera's marker pose in the world frame.

    Attributes:
        camera_id: e.g. ``cam1``.
        position: marker centre (3,), metres.
        normal: unit marker normal (3,).
        covariance: 6x6 covariance over (x, y, z, n_x, n_y, n_z) from the sensor model.
    """

    camera_id: str
    position: NDArray[np.float64]
    normal: NDArray[np.float64]
    covariance: NDArray[np.float64]

    @staticmethod
    def create(
        camera_id: str, position: ArrayLike, normal: ArrayLike, covariance: ArrayLike
    ) -> PoseReading:
        """Validate and build a reading.

        Raises:
            InvalidReadingError: for non-finite values, a zero normal, or a covariance that is not
                6x6 with a positive diagonal.
        """
        p = np.asarray(position, dtype=np.float64).reshape(-1)
        n = np.asarray(normal, dtype=np.float64).reshape(-1)
        c = np.asarray(covariance, dtype=np.float64)
        if c.size == 36:
            c = c.reshape(6, 6)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InvalidReadingError(f'{camera_id}: position must be 3 finite numbers')
        if n.shape != (3,) or not np.all(np.isfinite(n)):
            raise InvalidReadingError(f'{camera_id}: normal must be 3 finite numbers')
        norm = float(np.linalg.norm(n))
        if norm < 1e-9:
            raise InvalidReadingError(f'{camera_id}: normal has zero length')
        if c.shape != (6, 6) or not np.all(np.isfinite(c)):
            raise InvalidReadingError(f'{camera_id}: covariance must be a finite 6x6 matrix')
        if np.any(np.diag(c) <= 0.0):
            raise InvalidReadingError(
                f'{camera_id}: covariance diagonal must be positive, got {np.diag(c).tolist()}'
            )
        return PoseReading(camera_id, p, n / norm, 0.5 * (c + c.T))

    def values(self) -> NDArray[np.float64]:
        return np.concatenate([self.position, self.normal])


@dataclass(frozen=True)
class FusedPose:
    """The fused pose of one demand instant.

    Attributes:
        position: fused marker centre (3,).
        normal: fused unit normal (3,).
        covariance: 6x6 ``P = (sum R_i^-1)^-1`` over the cameras used.
        lower: optimal-region lower bound per variable (6,).
        upper: optimal-region upper bound per variable (6,).
        cameras_used: ids of the cameras whose readings agree.
        cameras_faulty: ids of the cameras judged faulty in at least one variable.
        regions: the per-variable Optimal Region results, in :data:`VARIABLES` order.
    """

    position: NDArray[np.float64]
    normal: NDArray[np.float64]
    covariance: NDArray[np.float64]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    cameras_used: tuple[str, ...]
    cameras_faulty: tuple[str, ...]
    regions: tuple[OptimalRegion, ...]


def fuse_poses(
    readings: Sequence[PoseReading], z: float = 3.0, max_faulty: int | None = None
) -> FusedPose:
    """Fuse camera readings variable by variable with Optimal Region.

    Args:
        readings: one reading per camera (at least one).
        z: abstract-sensor half-width in standard deviations (3: the paper's 99.74 %).
        max_faulty: k_f; ``None`` for the default largest k_f < k/2.

    Returns:
        The fused pose, its covariance, region bounds, and which cameras were used or faulty.

    Raises:
        InvalidReadingError: no readings, duplicate camera ids, or a bad z.
        NoConsensusError: when any variable has no probable region.
    """
    if not readings:
        raise InvalidReadingError('fuse_poses needs at least one reading')
    ids = [r.camera_id for r in readings]
    if len(set(ids)) != len(ids):
        raise InvalidReadingError(f'duplicate camera ids in readings: {ids}')
    if not (math.isfinite(z) and z > 0.0):
        raise InvalidReadingError(f'z must be finite and positive, got {z}')

    # Readings were validated on creation (finite, positive variances): build all abstract
    # sensors at once (eq. 5) instead of one call per reading and variable.
    values = np.array([r.values() for r in readings])
    deltas = z * np.sqrt(np.array([np.diag(r.covariance) for r in readings]))
    lows, highs = (values - deltas).T.tolist(), (values + deltas).T.tolist()
    k = len(readings)
    k_f = default_max_faulty(k) if max_faulty is None else int(max_faulty)
    if not 0 <= k_f < k:
        raise InvalidReadingError(f'max_faulty must be in 0..{k - 1} for {k} readings, got {k_f}')
    regions: list[OptimalRegion] = []
    faulty: set[int] = set()
    for v, name in enumerate(VARIABLES):
        intervals = list(zip(lows[v], highs[v], strict=True))
        try:
            region = optimal_region_unchecked(intervals, k_f)
        except NoConsensusError as exc:
            raise NoConsensusError(f'variable {name}: {exc}') from exc
        regions.append(region)
        faulty.update(region.faulty)

    used = [i for i in range(len(ids)) if i not in faulty]
    if not used:
        # Every camera was faulty in some variable: no subset agrees on the whole pose.
        raise NoConsensusError(
            'every camera disagrees with the others in at least one variable: '
            + ', '.join(
                f'{VARIABLES[v]} faulty {[ids[i] for i in r.faulty]}'
                for v, r in enumerate(regions)
                if r.faulty
            )
        )
    estimate = np.array([r.estimate for r in regions])
    normal = estimate[3:]
    norm = float(np.linalg.norm(normal))
    if norm < 1e-9:
        raise NoConsensusError('the fused normal has zero length')
    return FusedPose(
        position=estimate[:3],
        normal=normal / norm,
        covariance=information_fusion([readings[i].covariance for i in used]),
        lower=np.array([r.lower for r in regions]),
        upper=np.array([r.upper for r in regions]),
        cameras_used=tuple(ids[i] for i in used),
        cameras_faulty=tuple(ids[i] for i in sorted(faulty)),
        regions=tuple(regions),
    )


def weighted_mean_fusion(readings: Sequence[PoseReading]) -> NDArray[np.float64]:
    """Inverse-covariance weighted mean of all readings (the baseline with no fault tolerance).

    Returns the fused (x, y, z, n_x, n_y, n_z) with the normal renormalised.
    """
    P = information_fusion([r.covariance for r in readings])
    info_sum = sum((np.linalg.pinv(r.covariance) @ r.values() for r in readings), np.zeros(6))
    out = P @ info_sum
    out[3:] /= np.linalg.norm(out[3:])
    return np.asarray(out, dtype=np.float64)


def median_fusion(readings: Sequence[PoseReading]) -> NDArray[np.float64]:
    """Component-wise median of all readings (robust baseline), normal renormalised."""
    out = np.median(np.array([r.values() for r in readings]), axis=0)
    out[3:] /= np.linalg.norm(out[3:])
    return np.asarray(out, dtype=np.float64)
