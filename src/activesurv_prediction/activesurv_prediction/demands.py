"""Demand instants and the rolling horizon of predicted demand points (pure core).

In an experiment, demand instants are fixed in advance: either ``first + k * interval`` for
k = 0 .. count-1, or an explicit list (:class:`DemandSchedule`). In continuous surveillance each
object that crosses the workspace brings its own (:class:`DemandBook`): every ``interval``
seconds from its entry, or the predicted instants at which it crosses lines x = X (demands by
position, the paper's other option). The horizon at time ``now`` is the next ``m`` instants
after ``now``, each with the predicted pose of the surveyed target (the side marker). The xy
table only translates, so the side marker is the top marker plus a rigid offset, and its
normal is fixed.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.errors import GeometryError
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_prediction.base import Predictor
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.tracker import Tracker, TrackState

Array = NDArray[np.float64]


VELOCITY_STEP = 0.05  # s: half the span of the central difference for a demand's velocity


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
        first = bisect.bisect_right(self.times, now)
        return [(j, self.times[j]) for j in range(first, min(first + m, len(self.times)))]


@dataclass(frozen=True)
class TargetGeometry:
    """The object's geometry as the predictor uses it: the side marker relative to the top
    marker (object frame = world axes: no rotation), and how well that is known.

    Attributes:
        object: the object (:class:`~activesurv_common.object_geometry.ObjectGeometry`).
        z_std: std of the side marker's height (m): the geometry is known, not measured.
        normal_std: std of the normal components.
    """

    object: ObjectGeometry
    z_std: float = 0.5e-3
    normal_std: float = 0.01

    @property
    def offset(self) -> Array:
        """Side-marker centre minus top-marker centre (m)."""
        return self.object.offset

    @property
    def normal(self) -> Array:
        """Unit normal of the side marker in the world."""
        return self.object.normal

    @staticmethod
    def create(
        offset: ArrayLike, normal: ArrayLike, z_std: float = 0.5e-3, normal_std: float = 0.01
    ) -> TargetGeometry:
        """From a side marker's offset and normal (the rest of the object as the paper's).

        Raises:
            PredictionError: for anything but 3 finite numbers each, or a zero normal.
        """
        o = np.asarray(offset, dtype=np.float64).reshape(-1)
        n = np.asarray(normal, dtype=np.float64).reshape(-1)
        if o.shape != (3,) or n.shape != (3,):
            raise PredictionError('side marker offset and normal need 3 finite numbers each')
        try:
            obj = ObjectGeometry(
                side_offset=(float(o[0]), float(o[1]), float(o[2])),
                side_normal=(float(n[0]), float(n[1]), float(n[2])),
            )
        except GeometryError as exc:
            raise PredictionError(f'side marker: {exc}') from exc
        return TargetGeometry(obj, z_std, normal_std)


@dataclass(frozen=True)
class DemandPrediction:
    """Predicted side-marker pose at one demand instant.

    Attributes:
        index, instant: the demand.
        position: (3,) predicted marker centre (world).
        normal: (3,) marker normal.
        covariance: 6x6 over (x, y, z, rot_x, rot_y, rot_z).
        velocity: (3,) predicted marker velocity at the instant (m/s).
    """

    index: int
    instant: float
    position: Array
    normal: Array
    covariance: Array
    object_id: int = 0
    velocity: Array = field(default_factory=lambda: np.zeros(3))


def predict_demands(
    predictor: Predictor,
    schedule: DemandSchedule,
    geometry: TargetGeometry,
    top_height: float,
    now: float,
    m: int,
    object_id: int = 0,
) -> list[DemandPrediction]:
    """The rolling horizon: predicted target poses at the next ``m`` demand instants."""
    if predictor.last_time is None:
        return []
    upcoming = schedule.upcoming(max(now, predictor.last_time), m)
    return predict_points(predictor, upcoming, geometry, top_height, object_id)


def crossing_time(
    predictor: Predictor, x: float, now: float, ahead: float = 20.0, step: float = 0.2
) -> float | None:
    """The first instant after ``now`` at which the predicted path crosses the line x = ``x``,
    within ``ahead`` seconds, or None."""
    if predictor.last_time is None:
        return None
    t0 = max(now, predictor.last_time)
    f0 = float(predictor.predict_mean(t0)[0]) - x
    t = t0
    while t < t0 + ahead:
        t1 = t + step
        f1 = float(predictor.predict_mean(t1)[0]) - x
        if f0 == 0.0:
            return t
        if f0 * f1 < 0.0:
            return t + step * f0 / (f0 - f1)  # linear between the two samples
        t, f0 = t1, f1
    return None


class DemandBook:
    """The demands of the objects crossing the workspace one after another.

    Demand indices run on across objects (each demand has one, for good); object ids are given
    when a track is confirmed (1, 2, ...). Per object, the demand instants are either every
    ``interval`` seconds from its entry (the first fix of its track) plus ``phase``, or the
    predicted instants at which it crosses each of the lines x = X of ``lines_x``. A crossing
    instant follows the prediction until it is ``freeze`` seconds away, then stays (the
    dispatcher must know when to trigger). Only instants whose predicted point lies in
    ``region`` (x_min, x_max, y_min, y_max; None: anywhere) are demanded: where the cameras
    cannot serve, nothing is promised.
    A promise is kept: an instant is first demanded when its predicted point lies ``margin``
    inside the region, and then stays demanded while the point lies in the region, and for
    good from ``freeze`` seconds before it (the cameras are on their way). Without that, an
    object leaving across the region's edge near an instant made the demand come and go with
    the prediction's noise, and the dispatcher sent its cameras back and forth until the
    instant came with them in between; promising up to ``margin`` outside the region instead
    made demands the cameras could not serve. An entry is an overhead frame's stamp, so with an
    interval a multiple of the frame period every instant fell on an overhead frame, and at an
    instant the overhead camera and the tracker worked beside the imaging cameras: a ``phase``
    of half a frame period keeps them apart.

    Raises:
        PredictionError: for an interval <= 0 with no lines, bad lines/region, or a phase
            outside [0, interval).
    """

    def __init__(
        self,
        interval: float = 0.0,
        lines_x: Sequence[float] = (),
        region: Sequence[float] | None = None,
        freeze: float = 1.0,
        margin: float = 0.01,
        phase: float = 0.0,
    ) -> None:
        lines = tuple(float(v) for v in lines_x)
        if not all(math.isfinite(v) for v in lines) or not math.isfinite(interval):
            raise PredictionError('demand interval and lines must be finite')
        if not (math.isfinite(phase) and phase >= 0.0 and (phase < interval or phase == 0.0)):
            raise PredictionError(f'demand phase must be in [0, interval), got {phase}')
        self.phase = float(phase)
        if not lines and not interval > 0.0:
            raise PredictionError('continuous demands need an interval > 0 s or demand lines')
        if region is not None and len(region) != 4:
            raise PredictionError('demand region needs x_min, x_max, y_min, y_max')
        self.interval = float(interval)
        self.lines = lines
        self.region = None if region is None else tuple(float(v) for v in region)
        self.freeze = freeze
        self.margin = margin
        self.object_id = 0
        self.objects = 0
        self.entered: float | None = None
        self._next_index = 0
        self._index: dict[tuple[str, float], int] = {}
        self._frozen: dict[tuple[str, float], float] = {}
        self._promised: set[tuple[str, float]] = set()

    def start(self, entered: float) -> int:
        """A new object was confirmed; its track began at ``entered``. Returns its id."""
        self.objects += 1
        self.object_id = self.objects
        self.entered = entered
        self._index.clear()
        self._frozen.clear()
        self._promised.clear()
        return self.object_id

    def end(self) -> None:
        """The object left (or was lost): its demands still to come are dropped."""
        self.object_id = 0
        self.entered = None
        self._index.clear()
        self._frozen.clear()
        self._promised.clear()

    def _inside(self, xy: Array, margin: float = 0.0) -> bool:
        if self.region is None:
            return True
        x0, x1, y0, y1 = self.region
        return bool(x0 - margin <= xy[0] <= x1 + margin and y0 - margin <= xy[1] <= y1 + margin)

    def _demanded(self, key: tuple[str, float], t: float, now: float, xy: Array) -> bool:
        if key in self._promised:
            if t - now <= self.freeze or self._inside(xy):
                return True
            self._promised.discard(key)  # the object will be outside: withdrawn
            return False
        if self._inside(xy, -self.margin):
            self._promised.add(key)
            return True
        return False

    def upcoming(self, predictor: Predictor, now: float, m: int) -> list[tuple[int, float]]:
        """(index, instant) of the current object's next ``m`` demands after ``now``."""
        if self.object_id == 0 or self.entered is None or predictor.last_time is None:
            return []
        cands: list[tuple[float, tuple[str, float]]] = []
        if self.interval > 0.0:
            first = self.entered + self.phase
            k = max(1, math.floor((now - first) / self.interval) + 1)
            for n in range(k, k + 4 * m):
                cands.append((first + n * self.interval, ('t', float(n))))
        for x in self.lines:
            key = ('x', x)
            t = self._frozen.get(key)
            if t is None:
                t = crossing_time(predictor, x, now)
                if t is not None and t - now <= self.freeze:
                    self._frozen[key] = t
            if t is not None:
                cands.append((t, key))
        out: list[tuple[int, float]] = []
        for t, key in sorted(cands):
            if t <= now or len(out) >= m:
                continue
            # Indices follow the instants (the dispatcher serves the lowest index first), so
            # an instant gets one when it comes up, in the region or not; only those whose
            # predicted point is in the region are demanded (now).
            if key not in self._index:
                self._index[key] = self._next_index
                self._next_index += 1
            if self._demanded(key, t, now, predictor.predict_mean(t)):
                out.append((self._index[key], t))
        return out


def predict_points(
    predictor: Predictor,
    upcoming: Sequence[tuple[int, float]],
    geometry: TargetGeometry,
    top_height: float,
    object_id: int = 0,
) -> list[DemandPrediction]:
    """Predicted target poses at the given (index, instant) demands."""
    out = []
    predicted = predictor.predict_many([t for _, t in upcoming])
    template = np.diag([0.0, 0.0, geometry.z_std**2] + [geometry.normal_std**2] * 3)
    for (j, t), (mean, cov) in zip(upcoming, predicted, strict=True):
        pos = np.array([mean[0], mean[1], top_height]) + geometry.offset
        C = template.copy()
        C[:2, :2] = cov
        # The planar velocity by a difference of the predicted mean around t (never before the
        # filter's last update: it predicts forward only).
        t0 = max(t - VELOCITY_STEP, predictor.last_time or t)
        t1 = t0 + 2 * VELOCITY_STEP
        v = (predictor.predict_mean(t1)[:2] - predictor.predict_mean(t0)[:2]) / (t1 - t0)
        vel = np.array([v[0], v[1], 0.0])
        out.append(DemandPrediction(j, t, pos, geometry.normal.copy(), C, object_id, vel))
    return out


class ObjectDemands:
    """Continuous mode: an object id for each confirmed track, and that object's demands.

    The object ends when its track is lost or replaced by a new one (its demands still to come
    are dropped); the next confirmed track is the next object.
    """

    def __init__(self, book: DemandBook) -> None:
        self.book = book
        self._track = -1  # which of the tracker's tracks the current object is

    def update(
        self,
        tracker: Tracker,
        now: float,
        m: int,
        geometry: TargetGeometry,
        top_height: float,
    ) -> tuple[list[DemandPrediction], list[str]]:
        """The current object's next ``m`` demand points, and log lines of what changed."""
        events = []
        book = self.book
        if book.object_id and (
            tracker.state is not TrackState.CONFIRMED or tracker.tracks_started != self._track
        ):
            events.append(f'object {book.object_id} left; its demands end')
            book.end()
        if tracker.state is TrackState.CONFIRMED and not book.object_id:
            entered = tracker.started_at if tracker.started_at is not None else now
            oid = book.start(entered)
            self._track = tracker.tracks_started
            events.append(f'object {oid} confirmed (its track started at {entered:.2f} s)')
        if not book.object_id:
            return [], events
        upcoming = book.upcoming(tracker.predictor, now, m)
        return predict_points(
            tracker.predictor, upcoming, geometry, top_height, book.object_id
        ), events


def demand_source(
    mode: str,
    times: Sequence[float],
    regular: tuple[float, float, int],
    interval: float,
    lines_x: Sequence[float],
    region: Sequence[float],
    freeze: float,
    phase: float = 0.0,
) -> tuple[DemandSchedule, ObjectDemands | None]:
    """The predictor's demands from its parameters: the experiment's fixed schedule (explicit
    ``times``, else ``regular`` = first, interval, count), and in ``interval`` or ``lines``
    mode the per-object demands of continuous surveillance.

    Raises:
        PredictionError: for an unknown mode or bad values.
    """
    schedule = DemandSchedule.explicit(times) if times else DemandSchedule.regular(*regular)
    if mode == 'schedule':
        return schedule, None
    if mode not in ('interval', 'lines'):
        raise PredictionError(f'demand mode must be schedule, interval or lines, got {mode!r}')
    book = DemandBook(
        interval if mode == 'interval' else 0.0,
        [float(x) for x in lines_x] if mode == 'lines' else (),
        [float(x) for x in region],
        freeze,
        phase=phase if mode == 'interval' else 0.0,
    )
    return schedule, ObjectDemands(book)
