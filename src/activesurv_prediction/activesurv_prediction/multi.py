"""Several objects at once: one track per object from the overhead camera's fixes (pure core).

Each overhead frame gives every top marker it holds (``overhead/fixes``). The tracks are the
single-object :class:`~activesurv_prediction.tracker.Tracker` (an IMM each, its life cycle:
tentative, confirmed after ``confirm_fixes``, lost after ``lost_timeout`` or on leaving the
workspace), and each frame's fixes are shared out among them:

1. *Gating.* A fix may go to a track if its squared Mahalanobis distance from the track's
   prediction (prediction covariance plus the measurement's) is within ``gate`` (chi-square,
   2 degrees of freedom, 99.97 %), or, for a young track whose covariance says little yet, if
   it lies within ``near`` metres of the prediction.
2. *Assignment.* The fixes and tracks are paired by least total distance
   (``scipy.optimize.linear_sum_assignment``, the Hungarian method, on the squared Mahalanobis
   distances; gated-out pairs cost more than any gated pair).
3. *Birth.* A fix no track takes, inside the workspace, starts a new tentative track.
4. *Confirmation.* A track confirmed gets the next object id (1, 2, ...) and its demands.
5. *Death.* A track lost is dropped; its object's demands still to come end. A track is lost
   when the overhead stream has run ``lost_timeout`` past its last fix (frames kept coming
   without it), not when the clock has: a stream that lags the clock (a loaded machine, a slow
   locator) delivers its fixes late, not never. Only a stream that stalls for ``stream_grace``
   lets the clock decide.

Demand instants of several objects are staggered, as a cell schedules its inspections: each
object has one every ``interval`` seconds, offset so that instants of different objects are at
least ``interval`` / N apart (N: the most objects expected at once).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_prediction.demands import (
    DemandBook,
    DemandPrediction,
    TargetGeometry,
    predict_points,
)
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.predictor import make_predictor
from activesurv_prediction.tracker import (
    MotionSummary,
    Tracker,
    TrackEstimate,
    TrackState,
    Workspace,
)

Array = NDArray[np.float64]
GATE = 16.3  # chi-square, 2 dof, 99.97 %
NEAR = 0.02  # m: a young track takes a fix this close whatever its covariance says
_FAR = 1e6  # cost of a pair outside the gate


@dataclass
class Track:
    """One object's track and, once confirmed, its demands."""

    tracker: Tracker
    born: float
    object_id: int = 0  # given at confirmation
    book: DemandBook | None = None
    manoeuvres_before: int = 0  # of this track when it died (the count stays monotonic)

    @property
    def confirmed(self) -> bool:
        return self.tracker.state is TrackState.CONFIRMED

    @property
    def alive(self) -> bool:
        return self.tracker.state in (TrackState.TENTATIVE, TrackState.CONFIRMED)


@dataclass
class MultiTracker:
    """Tracks of every object on the table, and their demands (see the module)."""

    model: str = 'imm'
    measurement_std: float = 5e-4
    jerk_std: float = 2e-4
    confirm_fixes: int = 10
    workspace: Workspace = field(default_factory=Workspace)
    lost_timeout: float = 1.0
    interval: float = 10.0
    lines_x: Sequence[float] = ()
    region: Sequence[float] | None = None
    freeze: float = 1.0
    at_once: int = 2
    phase: float = 0.0  # interval mode: s after an entry's grid (DemandBook.phase)
    gate: float = GATE
    near: float = NEAR
    stream_grace: float = 2.0  # s a stalled overhead stream may lag the clock before loss
    stream_time: float = -math.inf  # the newest overhead frame's time
    tracks: list[Track] = field(default_factory=list)
    objects: int = 0
    manoeuvres_of_dead: int = 0
    _next_index: int = 0
    _index: dict[tuple[int, int], int] = field(default_factory=dict)
    _assign: Callable[[NDArray[np.float64]], tuple[NDArray[np.intp], NDArray[np.intp]]] = field(
        init=False, repr=False
    )

    def __post_init__(self) -> None:
        if self.at_once < 1:
            raise PredictionError(f'objects at once must be >= 1, got {self.at_once}')
        if not (math.isfinite(self.gate) and self.gate > 0 and self.near >= 0):
            raise PredictionError('gate must be > 0 and near >= 0')
        # Paid here, at the node's start, not on the first fix with a track: the first
        # association imports scipy.optimize (0.5 s alone, 3.5 s on a loaded 2-core host, where
        # it stalled the predictor and dispatcher for the first demands of two objects at
        # once), and a first tracker may import its filter's library (filterpy for 'ca').
        from scipy.optimize import linear_sum_assignment

        self._assign = linear_sum_assignment
        self._new_tracker()

    def _new_tracker(self) -> Tracker:
        return Tracker(
            make_predictor(
                self.model, measurement_std=self.measurement_std, jerk_std=self.jerk_std
            ),
            self.workspace,
            confirm_fixes=self.confirm_fixes,
            lost_timeout=self.lost_timeout,
        )

    # -- fixes -----------------------------------------------------------------------------
    def update(self, t: float, fixes: Sequence[ArrayLike]) -> list[str]:
        """One overhead frame's fixes (world x, y); returns log lines of what changed.

        Raises:
            PredictionError: for a non-finite time or fix.
        """
        if not math.isfinite(t):
            raise PredictionError(f'time must be finite, got {t!r}')
        z = [np.asarray(f, dtype=np.float64).reshape(2) for f in fixes]
        if any(not np.all(np.isfinite(v)) for v in z):
            raise PredictionError('fixes must be finite')
        events: list[str] = []
        late = t < self.stream_time  # a frame older than one already seen: no births from it
        self.stream_time = max(self.stream_time, t)
        live = [k for k in self.tracks if k.alive and k.tracker.predictor.last_time is not None]
        taken: set[int] = set()
        if live and z:
            cost = np.full((len(live), len(z)), _FAR)
            R = self.measurement_std**2 * np.eye(2)
            for i, k in enumerate(live):
                p = k.tracker.predictor
                if p.last_time is not None and t < p.last_time:
                    continue  # a stale frame for this track
                mean, cov = p.predict(max(t, p.last_time or t))
                S = np.asarray(cov).reshape(2, 2) + R
                try:
                    S_inv = np.linalg.inv(S)
                except np.linalg.LinAlgError:
                    continue
                young = not k.confirmed
                for j, v in enumerate(z):
                    d = v - mean
                    d2 = float(d @ S_inv @ d)
                    if d2 <= self.gate or (young and float(np.hypot(*d)) <= self.near):
                        cost[i, j] = min(d2, self.gate)
            rows, cols = self._assign(cost)
            for i, j in zip(rows, cols, strict=True):
                if cost[i, j] >= _FAR:
                    continue
                live[i].tracker.update(t, z[j])
                taken.add(int(j))
        for j, v in enumerate(z):
            if late or j in taken or not self.workspace.contains(v):
                continue
            if any(self._near_track(k, t, v) for k in self.tracks):
                continue  # a duplicate of a tracked marker (split blob): no new track
            k = Track(self._new_tracker(), t)
            k.tracker.update(t, v)
            self.tracks.append(k)
        events += self._housekeeping(t)
        return events

    def _near_track(self, k: Track, t: float, v: Array) -> bool:
        """Whether fix ``v`` at ``t`` lies within half ``near`` of live track ``k`` (where the
        track is at ``t``, or at its last update if ``t`` is a frame older than that)."""
        p = k.tracker.predictor
        if not k.alive or p.last_time is None:
            return False
        return float(np.hypot(*(v - p.predict_mean(max(t, p.last_time))))) < self.near / 2

    def check_timeout(self, now: float) -> list[str]:
        """Lose the tracks the overhead stream has not seen for ``lost_timeout`` (the clock
        ``now`` decides only once the stream lags it by ``stream_grace``); log lines of what
        changed."""
        reference = max(self.stream_time, now - self.stream_grace)
        for k in self.tracks:
            k.tracker.check_timeout(min(now, reference))
        return self._housekeeping(now)

    def _housekeeping(self, t: float) -> list[str]:
        events = []
        for k in self.tracks:
            if k.confirmed and not k.object_id:
                self.objects += 1
                k.object_id = self.objects
                k.book = self._book(k, t)
                events.append(
                    f'object {k.object_id} confirmed (its track started at {k.born:.2f} s)'
                )
        for k in [k for k in self.tracks if not k.alive]:
            self.manoeuvres_of_dead += k.tracker.manoeuvres.count
            if k.object_id:
                events.append(f'object {k.object_id} left; its demands end')
            self.tracks.remove(k)
        return events

    # -- demands ---------------------------------------------------------------------------
    def _book(self, track: Track, now: float) -> DemandBook:
        """The demands of a newly confirmed object, its instants staggered from the others'."""
        book = DemandBook(self.interval, self.lines_x, self.region, self.freeze, phase=self.phase)
        book.start(self._staggered_entry(track.born, now))
        book.object_id = track.object_id
        return book

    def _staggered_entry(self, born: float, now: float) -> float:
        """An entry time >= ``born`` whose instants (entry + n interval) keep interval / N
        from the other objects' (in phase modulo the interval)."""
        if self.interval <= 0.0:
            return born
        step = self.interval / self.at_once
        phases = [
            (k.book.entered % self.interval)
            for k in self.tracks
            if k.book is not None and k.book.entered is not None
        ]
        if not phases:
            return born
        base = phases[0]
        best, best_gap = born, -1.0
        for n in range(self.at_once):
            phase = (base + n * step) % self.interval
            gap = min(
                min(abs(phase - p) % self.interval, self.interval - abs(phase - p) % self.interval)
                for p in phases
            )
            entry = born + ((phase - born) % self.interval)
            if gap > best_gap + 1e-9:
                best, best_gap = entry, gap
        return best

    def horizon(
        self, now: float, m: int, geometry: TargetGeometry, top_height: float
    ) -> list[DemandPrediction]:
        """Every confirmed object's next ``m`` demand points, in time order; demand indices
        run on across objects (each demand has one, for good)."""
        out: list[DemandPrediction] = []
        for k in self.tracks:
            if k.book is None or not k.confirmed:
                continue
            upcoming = []
            for local, instant in k.book.upcoming(k.tracker.predictor, now, m):
                key = (k.object_id, local)
                if key not in self._index:
                    self._index[key] = self._next_index
                    self._next_index += 1
                upcoming.append((self._index[key], instant))
            out += predict_points(k.tracker.predictor, upcoming, geometry, top_height, k.object_id)
        if len(self._index) > 10_000:  # a session runs for hours
            live = {k.object_id for k in self.tracks}
            self._index = {key: j for key, j in self._index.items() if key[0] in live}
        return sorted(out, key=lambda d: (d.instant, d.index))

    # -- what it says ----------------------------------------------------------------------
    def state(self) -> TrackState:
        """CONFIRMED if any track is, else TENTATIVE if any lives, else NONE."""
        if any(k.confirmed for k in self.tracks):
            return TrackState.CONFIRMED
        return TrackState.TENTATIVE if self.tracks else TrackState.NONE

    def manoeuvre_count(self) -> int:
        """Manoeuvres of every track so far (dead ones included: it only grows)."""
        return self.manoeuvres_of_dead + sum(k.tracker.manoeuvres.count for k in self.tracks)

    def motion(self) -> MotionSummary:
        """The motion of the track whose demand comes next (else the first track's)."""
        confirmed = [k for k in self.tracks if k.confirmed]
        if not confirmed:
            return self.tracks[0].tracker.motion() if self.tracks else MotionSummary(())
        return confirmed[0].tracker.motion()

    def estimates(self, t: float) -> list[TrackEstimate]:
        """Every track's estimate at ``t`` (object id 0 while tentative)."""
        out = []
        for k in self.tracks:
            out += k.tracker.estimates(t, k.object_id)
        return out
