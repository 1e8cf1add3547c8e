"""Track management around the Kalman predictor: start, confirmation, loss (pure core).

* A track starts at the first fix inside the workspace (fixes outside are ignored: the object
  has not entered yet).
* It is confirmed after ``confirm_fixes`` accepted fixes; demand predictions are only
  trustworthy from then on.
* It is lost when the object leaves the workspace (by ``exit_margin``) or has not been seen for
  ``lost_timeout`` seconds; a fix inside the workspace starts a new track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_prediction.base import Predictor, UpdateResult
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.manoeuvre import ManoeuvreDetector
from activesurv_prediction.predictor import TargetPredictor


@dataclass(frozen=True)
class TrackEstimate:
    """Where a track puts its object now (the overhead tracks' output, for metrics and views).

    Attributes:
        object_id: the id its demands carry (0 before confirmation).
        confirmed: whether the track is confirmed.
        xy: filtered position (m, world) at the estimate's time.
        velocity: (m/s).
        covariance: 2x2 position covariance (m^2).
    """

    object_id: int
    confirmed: bool
    xy: NDArray[np.float64]
    velocity: NDArray[np.float64]
    covariance: NDArray[np.float64]


VELOCITY_STEP = 0.01  # s: a track's velocity is its prediction's slope over this step


class TrackState(Enum):
    """Mirrors the TRACK_* constants of ``activesurv_interfaces/DemandHorizon``."""

    NONE = 0
    TENTATIVE = 1
    CONFIRMED = 2
    LOST = 3


@dataclass(frozen=True)
class Workspace:
    """Axis-aligned region of the table the object moves in (m)."""

    x_min: float = 0.0
    x_max: float = 0.5
    y_min: float = 0.0
    y_max: float = 0.2

    def __post_init__(self) -> None:
        vals = (self.x_min, self.x_max, self.y_min, self.y_max)
        if (
            not all(math.isfinite(v) for v in vals)
            or self.x_min >= self.x_max
            or (self.y_min >= self.y_max)
        ):
            raise PredictionError(f'invalid workspace bounds {vals}')

    def contains(self, xy: ArrayLike, margin: float = 0.0) -> bool:
        x, y = np.asarray(xy, dtype=np.float64).reshape(2)
        return bool(
            self.x_min - margin <= x <= self.x_max + margin
            and self.y_min - margin <= y <= self.y_max + margin
        )


@dataclass(frozen=True)
class MotionSummary:
    """What the predictor makes of the object's motion now (for the horizon message)."""

    mode_names: tuple[str, ...] = ()
    probabilities: tuple[float, ...] = ()
    regime: str = ''
    manoeuvre: bool = False
    manoeuvre_count: int = 0


class Tracker:
    """Track life cycle of the object seen by the overhead camera."""

    def __init__(
        self,
        predictor: Predictor | None = None,
        workspace: Workspace | None = None,
        confirm_fixes: int = 10,
        lost_timeout: float = 1.0,
        exit_margin: float = 0.01,
    ) -> None:
        if confirm_fixes < 1 or not (math.isfinite(lost_timeout) and lost_timeout > 0):
            raise PredictionError('confirm_fixes must be >= 1 and lost_timeout > 0')
        self.predictor: Predictor = predictor or TargetPredictor()
        self.manoeuvres = ManoeuvreDetector()
        self.manoeuvre = False  # the last fix showed a manoeuvre
        self.workspace = workspace or Workspace()
        self.confirm_fixes = confirm_fixes
        self.lost_timeout = lost_timeout
        self.exit_margin = exit_margin
        self.state = TrackState.NONE
        self.last_seen: float | None = None
        self.started_at: float | None = None  # the first fix of the current track
        self.tracks_started = 0

    def update(self, t: float, xy: ArrayLike) -> UpdateResult | None:
        """Feed one fix. Returns the filter's verdict, or None if the fix was not used."""
        z = np.asarray(xy, dtype=np.float64).reshape(-1)
        if z.shape != (2,) or not np.all(np.isfinite(z)) or not math.isfinite(t):
            raise PredictionError(f'fix must be finite: t={t}, xy={xy!r}')
        if self.state in (TrackState.NONE, TrackState.LOST):
            if not self.workspace.contains(z):
                return None
            self.predictor.reset()
            self.manoeuvres.reset()
            self.state = TrackState.TENTATIVE
            self.tracks_started += 1
            self.started_at = t
        elif not self.workspace.contains(z, self.exit_margin):
            self.lose()
            return None
        if self.predictor.last_time is not None and t < self.predictor.last_time:
            return None  # a stale frame: drop it rather than break the time order
        result = self.predictor.update(t, z)
        self.manoeuvre = self.manoeuvres.update(
            self.predictor.mode_probabilities, result.restarted
        )
        if result.accepted:
            self.last_seen = t
        if self.state is TrackState.TENTATIVE and self.predictor.updates >= self.confirm_fixes:
            self.state = TrackState.CONFIRMED
        return result

    def motion(self) -> MotionSummary:
        """The mode probabilities, regime and manoeuvres of the current track."""
        if self.state not in (TrackState.TENTATIVE, TrackState.CONFIRMED):
            return MotionSummary(self.predictor.mode_names)
        return MotionSummary(
            self.predictor.mode_names,
            tuple(float(v) for v in self.predictor.mode_probabilities),
            self.manoeuvres.regime,
            self.manoeuvre,
            self.manoeuvres.count,
        )

    def check_timeout(self, now: float) -> bool:
        """Lose the track if the object has not been seen for ``lost_timeout``; True if lost."""
        active = self.state in (TrackState.TENTATIVE, TrackState.CONFIRMED)
        if active and self.last_seen is not None and now - self.last_seen > self.lost_timeout:
            self.lose()
            return True
        return False

    def lose(self) -> None:
        self.state = TrackState.LOST
        self.predictor.reset()

    def estimates(self, t: float, object_id: int = 0) -> list[TrackEstimate]:
        """The track's estimate at ``t`` (at or after its last fix); none without a track.
        ``object_id``: the id its demands carry (the demand source numbers objects)."""
        if self.state not in (TrackState.TENTATIVE, TrackState.CONFIRMED):
            return []
        if self.predictor.last_time is None:
            return []
        t = max(t, self.predictor.last_time)
        (xy, cov), (xy2, _) = self.predictor.predict_many([t, t + VELOCITY_STEP])
        return [
            TrackEstimate(
                object_id,
                self.state is TrackState.CONFIRMED,
                np.asarray(xy, dtype=np.float64),
                (np.asarray(xy2) - np.asarray(xy)) / VELOCITY_STEP,
                np.asarray(cov, dtype=np.float64).reshape(2, 2),
            )
        ]


def fix_statistics(fix_times: list[float], innovations: list[float]) -> dict[str, object]:
    """Diagnostics of the recent fixes: their rate and the innovations' squared Mahalanobis
    distances (mean and 95th percentile; a consistent filter has mean 2)."""
    ts = fix_times
    rate = (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 1 and ts[-1] > ts[0] else 0.0
    inn = np.array(innovations) if innovations else np.array([math.nan])
    return {
        'update_rate_hz': f'{rate:.1f}',
        'innovation_d2_mean': f'{float(np.mean(inn)):.2f}',
        'innovation_d2_p95': f'{float(np.percentile(inn, 95)):.2f}',
    }
