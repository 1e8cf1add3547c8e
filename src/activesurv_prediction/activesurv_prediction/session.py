"""The predictor's session core: overhead fixes in, the rolling horizon and the tracks out.

One object at a time (:class:`~activesurv_prediction.tracker.Tracker`: the experiments'
fixed schedule, or a session's per-object demands) or several at once
(:class:`~activesurv_prediction.multi.MultiTracker`). The ``predictor`` node and lockstep
mode drive this same object, so the two cannot drift apart: the node converts messages and
publishes what it returns.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from activesurv_prediction.base import UpdateResult
from activesurv_prediction.demands import (
    DemandPrediction,
    DemandSchedule,
    ObjectDemands,
    TargetGeometry,
    demand_source,
    predict_demands,
)
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.multi import MultiTracker
from activesurv_prediction.predictor import make_predictor
from activesurv_prediction.tracker import (
    MotionSummary,
    Tracker,
    TrackEstimate,
    TrackState,
    Workspace,
)


@dataclass(frozen=True)
class PredictorConfig:
    """Everything the predictor is told (``config/predictor.yaml``; SI units).

    Attributes:
        model: ``imm`` (manoeuvre-aware) or ``ca`` (constant acceleration).
        measurement_std: overhead fix std (m).
        jerk_std: ``ca`` model's process noise (m/s^3).
        gate: chi-square outlier gate (2 dof).
        confirm_fixes: fixes that confirm a track.
        lost_timeout: unseen s before a track is lost.
        workspace: x_min, x_max, y_min, y_max (m).
        horizon: demands on the rolling horizon (per object).
        marker_height: top marker plane z (m).
        side_offset: side minus top marker centre (m).
        side_normal: side marker normal (world).
        demand_mode: ``schedule`` (the experiments' fixed instants), ``interval`` or ``lines``
            (per object, continuous).
        demand_times: explicit instants (s); empty: ``first_demand`` + n ``service_interval``.
        first_demand, service_interval, demand_count: the regular schedule.
        demand_interval: interval mode: s between an object's demands.
        demand_phase: interval mode: s after the entry's grid (half an overhead frame period:
            no instant on an overhead frame).
        demand_lines: lines mode: x (m) of the lines whose crossings are demands.
        demand_region: where continuous demand points may fall.
        demand_freeze: lines mode: s before a crossing when it stops moving.
        objects_at_once: continuous: objects expected at once (> 1: every marker tracked).
    """

    model: str = 'imm'
    measurement_std: float = 0.5e-3
    jerk_std: float = 2e-4
    gate: float = 50.0
    confirm_fixes: int = 10
    lost_timeout: float = 1.0
    workspace: tuple[float, float, float, float] = (0.0, 0.5, 0.0, 0.2)
    horizon: int = 5
    marker_height: float = 0.08
    side_offset: tuple[float, float, float] = (0.0, -0.03, -0.03)
    side_normal: tuple[float, float, float] = (0.0, -1.0, 0.0)
    demand_mode: str = 'schedule'
    demand_times: tuple[float, ...] = ()
    first_demand: float = 4.0
    service_interval: float = 2.0
    demand_count: int = 10
    demand_interval: float = 2.0
    demand_phase: float = 0.0
    demand_lines: tuple[float, ...] = (0.25,)
    demand_region: tuple[float, float, float, float] = (0.0, 0.5, 0.0, 0.2)
    demand_freeze: float = 1.0
    objects_at_once: int = 1

    def __post_init__(self) -> None:
        if self.model not in ('imm', 'ca'):
            raise PredictionError(f'model must be imm or ca, got {self.model!r}')
        if self.horizon < 1 or self.confirm_fixes < 1 or self.objects_at_once < 1:
            raise PredictionError('horizon, confirm_fixes and objects_at_once must be >= 1')
        if self.objects_at_once > 1 and self.demand_mode == 'schedule':
            raise PredictionError('several objects at once need demand_mode interval or lines')
        for name in ('measurement_std', 'jerk_std', 'gate', 'lost_timeout'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise PredictionError(f'{name} must be finite and > 0, got {v}')
        Workspace(*self.workspace)  # raises for bad bounds

    # The node's parameter names where they differ from the fields' (config/predictor.yaml).
    RENAMED: ClassVar[dict[str, str]] = {
        'side_offset': 'side_marker_offset',
        'side_normal': 'side_marker_normal',
    }

    def to_parameters(self) -> dict[str, object]:
        """The ``predictor`` node's parameters that say the same."""
        out: dict[str, object] = {}
        for f in fields(self):
            name = f.name
            value = getattr(self, name)
            if isinstance(value, tuple):
                value = [float(v) for v in value]
            out[self.RENAMED.get(name, name)] = value
        if not self.demand_times:
            del out['demand_times']  # unset: the regular schedule
        return out

    @classmethod
    def from_parameters(cls, values: Mapping[str, Any]) -> PredictorConfig:
        """The config of a ``predictor`` node's parameter values (missing ones: defaults).

        Raises:
            PredictionError: for a bad value.
        """
        kwargs: dict[str, Any] = {}
        for f in fields(cls):
            name = f.name
            key = cls.RENAMED.get(name, name)
            if key not in values or values[key] is None:
                continue
            v = values[key]
            default = f.default
            try:
                if isinstance(default, tuple):
                    v = tuple(float(x) for x in v)
                    if default and len(v) != len(default) and name != 'demand_lines':
                        raise PredictionError(f'{key} needs {len(default)} numbers, got {v}')
                elif isinstance(default, bool):
                    v = bool(v)
                elif isinstance(default, int):
                    v = int(v)
                elif isinstance(default, float):
                    v = float(v)
                else:
                    v = str(v)
            except (TypeError, ValueError) as exc:
                raise PredictionError(f'{key}: {exc}') from exc
            kwargs[name] = v
        return cls(**kwargs)


@dataclass
class HorizonUpdate:
    """What one fix (or tick) produced, for the caller to publish.

    Attributes:
        demands: the rolling horizon (every object's, in time order).
        state: the track state to report.
        motion: mode probabilities, regime and manoeuvre count.
        tracks: every track's estimate now.
        stamp: the time of the fix it rests on.
        events: log lines of what changed (objects confirmed or gone, manoeuvres).
        accepted: the fix was accepted by its track (one object at a time).
        mahalanobis2: that fix's squared innovation distance (nan if none).
    """

    demands: list[DemandPrediction]
    state: TrackState
    motion: MotionSummary
    tracks: list[TrackEstimate]
    stamp: float
    events: list[str] = field(default_factory=list)
    accepted: bool = False
    mahalanobis2: float = math.nan


class PredictionSession:
    """Fixes in, horizons out (see the module)."""

    def __init__(self, config: PredictorConfig) -> None:
        self.config = c = config
        self.schedule: DemandSchedule
        self.objects: ObjectDemands | None
        self.schedule, self.objects = demand_source(
            c.demand_mode,
            list(c.demand_times),
            (c.first_demand, c.service_interval, c.demand_count),
            c.demand_interval,
            list(c.demand_lines),
            list(c.demand_region),
            c.demand_freeze,
            c.demand_phase,
        )
        self.geometry = TargetGeometry.create(c.side_offset, c.side_normal)
        self.tracker = Tracker(
            make_predictor(
                c.model, measurement_std=c.measurement_std, jerk_std=c.jerk_std, gate=c.gate
            ),
            Workspace(*c.workspace),
            confirm_fixes=c.confirm_fixes,
            lost_timeout=c.lost_timeout,
        )
        self.multi: MultiTracker | None = None
        if c.objects_at_once > 1:
            assert self.objects is not None  # PredictorConfig refuses a schedule
            book = self.objects.book
            self.multi = MultiTracker(
                c.model,
                c.measurement_std,
                c.jerk_std,
                c.confirm_fixes,
                Workspace(*c.workspace),
                c.lost_timeout,
                book.interval,
                book.lines,
                book.region,
                book.freeze,
                c.objects_at_once,
                phase=book.phase,
            )
        self._last_state = TrackState.NONE

    # -- inputs ----------------------------------------------------------------------------
    def on_fix(self, t: float, xy: ArrayLike) -> HorizonUpdate | None:
        """One object's overhead fix; None when the tracker did not use it.

        Raises:
            PredictionError: for a non-finite time or fix.
        """
        result: UpdateResult | None = self.tracker.update(t, xy)
        if result is None:
            return None
        out = self.horizon(t)
        out.accepted = bool(result.accepted)
        out.mahalanobis2 = float(result.mahalanobis2)
        return out

    def on_fixes(self, t: float, fixes: Sequence[ArrayLike]) -> HorizonUpdate:
        """Every top marker of one overhead frame (several objects at once).

        Raises:
            PredictionError: if the session tracks one object at a time, or for bad fixes.
        """
        if self.multi is None:
            raise PredictionError('fixes of several objects need objects_at_once > 1')
        events = self.multi.update(t, fixes)
        out = self.horizon(self.multi.stream_time)  # a late frame does not turn time back
        out.events = events + out.events
        return out

    def tick(self, now: float) -> HorizonUpdate | None:
        """Lose tracks not seen for ``lost_timeout``; the new horizon if that changed it."""
        if self.multi is not None:
            events = self.multi.check_timeout(now)
            if not events:
                return None
            out = self.horizon(now)
            out.events = events + out.events
            return out
        if self.tracker.check_timeout(now):
            out = self.horizon(now)
            out.events.insert(0, 'track lost: object not seen for too long')
            return out
        return None

    # -- output ----------------------------------------------------------------------------
    def horizon(self, now: float) -> HorizonUpdate:
        """The rolling horizon as of ``now`` (the time of the latest fix)."""
        c = self.config
        if self.multi is not None:
            m = self.multi
            motion = replace(m.motion(), manoeuvre_count=m.manoeuvre_count())
            every = m.horizon(now, c.horizon, self.geometry, c.marker_height)
            return HorizonUpdate(every, m.state(), motion, m.estimates(now), now)
        state = self.tracker.state
        events: list[str] = []
        preds: list[DemandPrediction] = []
        if self.objects is not None:
            preds, events = self.objects.update(
                self.tracker, now, c.horizon, self.geometry, c.marker_height
            )
        elif state in (TrackState.TENTATIVE, TrackState.CONFIRMED):
            preds = predict_demands(
                self.tracker.predictor,
                self.schedule,
                self.geometry,
                c.marker_height,
                now,
                c.horizon,
            )
        if self.tracker.manoeuvre:
            events.append(f'manoeuvre: the object is {self.tracker.manoeuvres.regime}')
        if state is not self._last_state:
            events.append(f'track {self._last_state.name} -> {state.name}')
            self._last_state = state
        # A session numbers its objects at confirmation; an experiment has its tracks.
        object_id = (
            self.objects.book.object_id
            if self.objects is not None
            else self.tracker.tracks_started
        )
        return HorizonUpdate(
            preds,
            state,
            self.tracker.motion(),
            self.tracker.estimates(now, object_id),
            now,
            events,
        )

    def state(self) -> TrackState:
        return self.multi.state() if self.multi is not None else self.tracker.state

    def status(self) -> dict[str, object]:
        """Diagnostics values beyond the fix statistics."""
        t = self.tracker
        values: dict[str, object] = {
            'track_state': self.state().name,
            'outliers_rejected': t.predictor.rejections,
            'tracks_started': t.tracks_started,
            'motion': t.manoeuvres.regime or '-',
            'manoeuvres': t.manoeuvres.count,
        }
        if self.multi is not None:
            values.update(
                tracks=len(self.multi.tracks),
                confirmed=sum(1 for k in self.multi.tracks if k.confirmed),
                objects_seen=self.multi.objects,
                manoeuvres=self.multi.manoeuvre_count(),
            )
        return values


def finite_fix(xy: ArrayLike) -> np.ndarray | None:
    """``xy`` as a (2,) float array, or None when it is not two finite numbers."""
    v = np.asarray(xy, dtype=np.float64).reshape(-1)
    return v if v.shape == (2,) and np.all(np.isfinite(v)) else None
