"""The evaluation of a continuous session from its bag: per demand the experiment's record plus
the object it was for; per object its pass over the table; the overhead tracking's metrics.

``results.json`` of a session: ``{"mode": "surveil", "objects": [{"id", "entered", "left",
"path_kind", ...}], "demands": [... the experiment's keys + "object"], "summary": {...}}``.
"""

from __future__ import annotations

import statistics
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_common.occlusion import PLATE_HALF_SIZE, obstacles_to_list, plate_box
from activesurv_common.sensor_model import SensorModel
from activesurv_common.timeseries import TimeSeries
from activesurv_evaluation.records import (
    DEMAND_TOPICS,
    TRUTH_TOLERANCE,
    DemandMessages,
    demand_record,
    msg_stamp,
    msg_vector,
    run_obstacles,
)
from activesurv_evaluation.timing import StepTimes, published, step_topics
from activesurv_evaluation.tracking import TrackRecorder, track_metrics
from activesurv_recording.bagio import read_bag
from activesurv_recording.errors import BagError
from activesurv_recording.run_record import RunRecord, SessionRun, read_run_record
from activesurv_sim.stream import ObjectStream

SESSION_TOPICS = DEMAND_TOPICS


def evaluate_surveil(bag: Path) -> dict[str, Any]:
    """The results document of a continuous session, from its bag (split or not).

    Every demand that got a capture request (a promise to the user) has a record; demands
    withdrawn before their request (the object left first) have none.

    Raises:
        BagError: for a missing, damaged or foreign bag.
    """
    record = read_run_record(bag)
    if not isinstance(record.run, SessionRun):
        raise BagError(f'bag {bag} is not a surveil session (a {record.kind})')
    session = record.run
    origin = record.time_origin  # a hardware session: wall clock
    st = session.stream
    stream = ObjectStream(
        st.seed,
        st.arrival_interval,
        st.first_entry,
        list(st.kinds),
        speed=st.speed,
        acceleration=st.acceleration,
        at_once=st.at_once,
        script=st.script,
    )

    def truth_id(t: float) -> int:
        p = stream.pass_at(t - origin)
        return 0 if p is None else int(p.id)

    heard = _SessionBag(TrackRecorder(truth_id))
    for m in read_bag(bag, SESSION_TOPICS | step_topics(record.initial_poses)):
        heard.hear(m)
    obstacles = run_obstacles(record)
    demands = _demand_rows(heard, record, obstacles)
    objects = _object_rows(heard, stream, demands, origin)
    lat = [d['latency'] for d in demands if d.get('latency') is not None]
    tracking = heard.tracked.metrics() if record.truth is not None else track_metrics([], [])
    on_rig = record.hardware
    return {
        'mode': 'surveil',
        **({'set': session.set_name} if session.set_name else {}),
        'system': record.system,
        'seed': record.seed,
        'demand_mode': session.demands.mode,
        'simulated_seconds': heard.end - origin,
        **({'hardware': on_rig.hardware, 'truth': on_rig.truth} if on_rig is not None else {}),
        'objects': objects,
        'obstacles': obstacles_to_list(obstacles or ()),
        'demands': demands,
        'summary': {
            'demands': len(demands),
            'ok': sum(1 for d in demands if d['status'] == 'ok'),
            'objects': len(objects),
            'latency_median_ms': 1e3 * statistics.median(lat) if lat else None,
            **tracking,
        },
    }


class _SessionBag(DemandMessages):
    """What a session's bag says, gathered message by message."""

    def __init__(self, tracked: TrackRecorder) -> None:
        super().__init__()
        self.tracked = tracked
        # One truth per lane (several objects at once publish a state per lane and tick).
        self.truths: dict[int, TimeSeries] = {}
        self.presents: dict[int, TimeSeries] = {}
        self.steps = StepTimes()
        self.object_of: dict[int, int] = {}
        self.confirmed: dict[int, float] = {}
        self.end = 0.0

    def hear(self, m: Any) -> None:
        self.end = max(self.end, m.t_ns * 1e-9)
        if self.steps.hear(m.topic, m.msg, m.t_ns * 1e-9) or self.hear_demand(m):
            return
        if m.topic == '/object_state':
            t = msg_stamp(m.msg)
            slot = int(getattr(m.msg, 'slot', 0))
            if slot not in self.truths:
                self.truths[slot] = TimeSeries(6, capacity=10**7)
                self.presents[slot] = TimeSeries(1, capacity=10**7)
            self.truths[slot].add(
                t, np.r_[msg_vector(m.msg.side_marker), msg_vector(m.msg.side_normal)]
            )
            self.presents[slot].add(t, [1.0 if m.msg.in_workspace else 0.0])
            self.tracked.on_truth(t, m.msg)
        elif m.topic == '/object_tracks':
            self.tracked.on_tracks(msg_stamp(m.msg), m.msg)
        elif m.topic == '/demand_horizon':
            for d in m.msg.demands:
                oid = int(d.object_id)
                self.object_of[int(d.index)] = oid
                self.confirmed.setdefault(oid, msg_stamp(m.msg))


def _demand_rows(heard: _SessionBag, record: RunRecord, obstacles: Any) -> list[dict[str, Any]]:
    """A row per demand with a request or an answer: the experiment's keys, ``t``, ``object``."""
    model = SensorModel.load()
    rows = []
    for j in sorted(set(heard.requests) | set(heard.estimates)):
        req = heard.requests.get(j)
        tj = (
            float(req.demand_instant.sec) + 1e-9 * float(req.demand_instant.nanosec)
            if req is not None
            else msg_stamp(heard.estimates[j][0])
        )
        here = _objects_at(heard.truths, heard.presents, tj)
        if not here:
            parked = heard.truths[0].at(tj, hold=0.5) if 0 in heard.truths else None
            if parked is None:
                continue
            here = [parked]
        guess = (
            msg_vector(req.predicted_position)
            if req is not None
            else msg_vector(heard.estimates[j][0].position)
        )
        s = _nearest(here, guess)
        blocking = None
        if obstacles is not None:  # the other objects' plates stand in the way too
            blocking = list(obstacles) + [
                plate_box(o[:3], o[3:], PLATE_HALF_SIZE)
                for o in here
                if o is not s and np.all(np.isfinite(o))
            ]
        observed = heard.observations.get(j, [])
        est = heard.estimates.get(j)
        rec = demand_record(
            j, tj, s, req, [o for o, _ in observed], est, model, blocking, record.marker_radius
        )
        rec.timing = heard.steps.timing(
            tj,
            rec.assigned,
            observed,
            None if est is None else est[1] * 1e-9,
            None if est is None else published(est[0]),
            None if est is None else published(est[0], 'compute_time'),
        )
        doc = rec.to_json()
        doc['t'] = tj - record.time_origin
        doc['object'] = heard.object_of.get(j, 0)
        rows.append(doc)
    return rows


def _object_rows(
    heard: _SessionBag, stream: ObjectStream, demands: list[dict[str, Any]], origin: float
) -> list[dict[str, Any]]:
    """A row per object the overhead camera confirmed: its pass and its number of demands."""
    objects = []
    for oid, t in sorted(heard.confirmed.items()):
        if oid == 0:
            continue
        p = _pass_of(stream, heard.tracked, oid, t - origin, origin)
        objects.append(
            {
                'id': oid,
                'entered': None if p is None else p.entered,
                'left': None if p is None or p.left > heard.end - origin else p.left,
                'path_kind': None if p is None else p.kind,
                'truth_id': None if p is None else p.id,
                'confirmed': t - origin,
                'demands': sum(1 for d in demands if d['object'] == oid),
            }
        )
    return objects


def _pass_of(
    stream: ObjectStream, tracked: TrackRecorder, oid: int, t: float, origin: float
) -> Any:
    """The stream's object that track ``oid`` followed, confirmed at run time ``t``: the one
    on the table then (several at once: the one nearest the track's first estimate)."""
    passes = stream.passes_at(t)
    if len(passes) <= 1:
        return passes[0] if passes else stream.pass_at(t)
    for stamp, items in sorted(tracked.tracks):
        for i, x, y in items:
            if i == oid:
                xy = np.array([x, y])
                return min(
                    passes,
                    key=lambda p: float(
                        np.linalg.norm(p.path.position(stamp - origin - p.entered) - xy)
                    ),
                )
    return passes[0]


def _objects_at(
    truths: dict[int, TimeSeries], presents: dict[int, TimeSeries], t: float
) -> list[np.ndarray]:
    """Side marker and normal (6,) of every object on the table at ``t``: its states around
    ``t`` interpolated; NaN for an object on the table whose states do not reach ``t`` (a stop
    ended the table first: its last state held would be a stale truth, 5 mm off for an object
    at 20 mm/s 0.25 s on), so that its demand is kept without errors, as an experiment's."""
    out = []
    for slot, series in truths.items():
        here = presents[slot].at(t, hold=0.5)
        if here is None or here[0] <= 0.5:
            continue
        s = series.at(t, hold=TRUTH_TOLERANCE)
        out.append(s if s is not None else np.full(6, np.nan))
    return out


def _nearest(here: list[np.ndarray], guess: np.ndarray) -> np.ndarray:
    """The object of ``here`` nearest ``guess`` (one whose truth is unknown only if no other
    is known)."""
    known = [v for v in here if np.all(np.isfinite(v))]
    if not known:
        return here[0]
    return min(known, key=lambda v: float(np.linalg.norm(v[:3] - guess)))
