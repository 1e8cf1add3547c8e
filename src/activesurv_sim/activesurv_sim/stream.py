"""A stream of objects crossing the xy table one after another (pure core).

Continuous surveillance watches object after object, as a production cell does: each object
enters at one end of the table, crosses it on a path of its own and leaves at the other end;
the next enters ``arrival_interval`` seconds after the previous one entered, but never before
the previous one has left plus ``gap`` seconds (the table carries one object at a time).

Paths are drawn from a seeded generator, each of one kind (:data:`PATH_KINDS`): straight lines,
parabolas, s-curves, circular arcs, lines with a stop of 1-6 s, lines with a speed step (8
mm/s, then the full speed), reversals (forward, back 4-10 cm, forward again) and random smooth
paths. All stay on the table and within ``speed`` (20 mm/s, the paper's object speed), with
acceleration ramps and a standstill at every stop and turn. While no object is on the table
its state is parked far outside every camera's view (``in_workspace`` false).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from activesurv_common.errors import GeometryError
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_sim.rig import load_rig
from activesurv_sim.xytable import (
    PARKED,
    TABLE_RANGE,
    ObjectState,
    TimedPath,
    XYTable,
    check_in_table,
    named_path,
    object_state,
)
from activesurv_stages.errors import ConfigError

Array = NDArray[np.float64]

PATH_KINDS = (
    'line',
    'parabola',
    's_curve',
    'arc',
    'stop',
    'speed_change',
    'reversal',
    'smooth',
)
_MARGIN = 0.015  # m from the table's edges
MAX_AT_ONCE = 4  # lanes the table has room for
LANE_MARGIN = 0.015  # m: objects in neighbouring lanes stay 30 mm apart at least
_X0, _X1 = TABLE_RANGE[0][0] + _MARGIN, TABLE_RANGE[0][1] - _MARGIN
_Y0, _Y1 = TABLE_RANGE[1][0] + 0.03, TABLE_RANGE[1][1] - 0.03


def travel(
    points: Sequence[Sequence[float]] | Array,
    speeds: Sequence[float],
    stops: dict[int, float],
    acceleration: float,
    dt: float = 0.01,
) -> TimedPath:
    """Time a polyline: segment i at up to ``speeds[i]``, coming to rest and waiting
    ``stops[i]`` seconds at vertex i (its start is vertex 0); at rest at both ends.

    Raises:
        ConfigError: for a degenerate polyline or non-positive speeds/acceleration.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise ConfigError('a path needs at least two finite (x, y) points')
    if len(speeds) != len(pts) - 1 or min(speeds) <= 0.0 or acceleration <= 0.0:
        raise ConfigError('one positive speed per segment and an acceleration > 0 are needed')
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s_vertex = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s_vertex[-1])
    if total <= 0.0:
        raise ConfigError('the path has zero length')
    rest = sorted(float(s_vertex[i]) for i in stops if 0 < i < len(pts) - 1) + [total]
    dwell = {float(s_vertex[i]): w for i, w in stops.items() if 0 < i < len(pts) - 1}
    t, s, v = 0.0, 0.0, 0.0
    ts, ss = [0.0], [0.0]
    while s < total - 1e-9:
        i = min(int(np.searchsorted(s_vertex, s, side='right')) - 1, len(speeds) - 1)
        nxt = next(r for r in rest if r > s + 1e-9)
        # Never faster than allows stopping at the next rest point.
        v_cap = min(speeds[i], math.sqrt(max(2.0 * acceleration * (nxt - s), 0.0)))
        v = min(v + acceleration * dt, v_cap) if v < v_cap else max(v - acceleration * dt, v_cap)
        v = max(v, 1e-4)  # creep the last micrometres
        s = min(s + v * dt, nxt)
        t += dt
        ts.append(t)
        ss.append(s)
        if s >= nxt - 1e-9 and nxt in dwell:
            v = 0.0
            wait = dwell.pop(nxt)
            if wait > 0.0:
                t += wait
                ts.append(t)
                ss.append(s)
    arc = np.asarray(ss)
    xy = np.column_stack(
        [np.interp(arc, s_vertex, pts[:, 0]), np.interp(arc, s_vertex, pts[:, 1])]
    )
    check_in_table(xy, 'the generated path')
    return TimedPath(np.asarray(ts), xy)


def random_path(
    kind: str, rng: np.random.Generator, speed: float = 0.02, acceleration: float = 0.02
) -> TimedPath:
    """One crossing of the table of the given kind, drawn from ``rng``.

    Raises:
        ConfigError: for an unknown kind.
    """
    if kind not in PATH_KINDS:
        raise ConfigError(f'unknown path kind {kind!r}; use one of {PATH_KINDS}')
    left_to_right = bool(rng.random() < 0.5)
    xa, xb = (_X0, _X1) if left_to_right else (_X1, _X0)
    ya, yb = rng.uniform(_Y0, _Y1, size=2)
    xs = np.linspace(xa, xb, 60)
    u = (xs - xa) / (xb - xa)  # 0 .. 1 along the crossing
    ys = ya + (yb - ya) * u
    speeds = None
    stops: dict[int, float] = {}
    if kind == 'line':
        pts = np.column_stack([[xa, xb], [ya, yb]])
    elif kind in ('parabola', 'arc'):
        ym = 0.5 * (_Y0 + _Y1)
        bulge = rng.uniform(0.04, 0.07) * rng.choice([-1.0, 1.0])
        ya = yb = ym - bulge / 2
        if kind == 'parabola':
            ys = ya + bulge * 4.0 * u * (1.0 - u)
        else:  # a circular arc through both ends with the same sagitta
            half = abs(xb - xa) / 2
            r = (half**2 + bulge**2) / (2 * abs(bulge))
            dx = xs - (xa + xb) / 2
            ys = ya + math.copysign(1.0, bulge) * (np.sqrt(r**2 - dx**2) - (r - abs(bulge)))
        pts = np.column_stack([xs, ys])
    elif kind == 's_curve':
        amp = rng.uniform(0.02, 0.045)
        ym = 0.5 * (_Y0 + _Y1)
        pts = np.column_stack([xs, ym + amp * np.sin(2.0 * math.pi * u)])
    elif kind == 'smooth':
        knots = rng.uniform(_Y0 + 0.01, _Y1 - 0.01, size=5)
        ys = np.interp(u, np.linspace(0.0, 1.0, 5), knots)
        ys = np.convolve(np.pad(ys, 7, mode='edge'), np.ones(15) / 15, mode='valid')
        pts = np.column_stack([xs, ys])
    elif kind == 'stop':
        f = rng.uniform(0.3, 0.7)
        pts = np.column_stack([[xa, xa + f * (xb - xa), xb], [ya, ya + f * (yb - ya), yb]])
        stops = {1: float(rng.uniform(1.0, 6.0))}
    elif kind == 'speed_change':
        f = rng.uniform(0.3, 0.6)
        pts = np.column_stack([[xa, xa + f * (xb - xa), xb], [ya, ya + f * (yb - ya), yb]])
        speeds = [min(0.008, speed), speed]
    else:  # reversal
        f = rng.uniform(0.4, 0.65)
        back = rng.uniform(0.04, 0.10) * math.copysign(1.0, xb - xa)
        xm = xa + f * (xb - xa)
        ym = ya + f * (yb - ya)
        pts = np.column_stack([[xa, xm, xm - back, xb], [ya, ym, ym, yb]])
        stops = {1: 0.0, 2: 0.0}
    n_seg = len(pts) - 1
    return travel(pts, speeds or [speed] * n_seg, stops, acceleration)


@dataclass(frozen=True)
class ObjectPass:
    """One object's crossing: its truth id, path kind, entry and exit (simulated s)."""

    id: int
    kind: str
    entered: float
    path: TimedPath
    slot: int = 0  # its lane on the table (several objects at once: one per lane)

    @property
    def left(self) -> float:
        return self.entered + self.path.duration


class ObjectStream:
    """Objects entering from ``first_entry`` on, paths drawn from ``seed``.

    With ``at_once`` = 1 (the default) the table carries one object at a time: the next enters
    ``arrival_interval`` s after the previous one entered, but never before it left plus
    ``gap``. With ``at_once`` = N > 1, up to N objects cross at once, each in a lane of its own
    (the table's y range cut in N bands, the path drawn for the whole range and narrowed into
    its band, 15 mm from the band's edges: neighbours stay 30 mm apart). The next object
    enters ``arrival_interval`` / N s after the previous one, in a free lane (one whose last
    object left ``gap`` s before), so arrivals overlap; crossings go in both directions,
    nearer and farther from the cameras.

    Args:
        seed: seeds the path kinds and shapes (the same seed, the same stream).
        arrival_interval: s from one object's entry to the next's (at the earliest), for one
            object at a time.
        first_entry: simulated s at which the first object enters.
        kinds: path kinds to draw from (default all of :data:`PATH_KINDS`).
        gap: s a lane stays empty between two objects at least.
        model: the markers relative to the carriage.
        position_error: the rig's table error map, as for :class:`XYTable` (None: exact).
        at_once: how many objects may be on the table at once (its lanes).
        script: the objects themselves instead of drawn ones (a named experiment set's
            scene): each ``{enter: s, slot: lane, path: {type: line|parabola, points:
            [...]}}``, its path as given (not narrowed into a lane); no object after them.
            ``at_once`` becomes the number of lanes the script uses.
    """

    def __init__(
        self,
        seed: int,
        arrival_interval: float = 30.0,
        first_entry: float = 1.0,
        kinds: Sequence[str] = PATH_KINDS,
        gap: float = 2.0,
        speed: float = 0.02,
        acceleration: float = 0.02,
        model: ObjectGeometry | None = None,
        position_error: Callable[[float, float], Array] | None = None,
        at_once: int = 1,
        script: Sequence[Mapping[str, Any]] = (),
    ) -> None:
        scripted = scripted_passes(script, speed, acceleration) if script else []
        if scripted:
            at_once = max(p.slot for p in scripted) + 1
        if not (math.isfinite(arrival_interval) and arrival_interval > 0.0 and gap >= 0.0):
            raise ConfigError('arrival_interval must be > 0 s and gap >= 0 s')
        if not 1 <= at_once <= MAX_AT_ONCE:
            raise ConfigError(f'objects at once must be 1 to {MAX_AT_ONCE}, got {at_once}')
        bad = [k for k in kinds if k not in PATH_KINDS]
        if bad or not kinds:
            raise ConfigError(f'path kinds must be among {PATH_KINDS}, got {list(kinds)}')
        self.rng = np.random.default_rng(seed)
        self.arrival_interval = arrival_interval
        self.kinds = tuple(kinds)
        self.gap = gap
        self.speed = speed
        self.acceleration = acceleration
        self.model = model or ObjectGeometry()
        n = np.asarray(self.model.side_normal, dtype=np.float64)
        self._normal = n / np.linalg.norm(n)
        self.passes: list[ObjectPass] = []
        self._next_entry = first_entry
        self.position_error = position_error
        self.at_once = at_once
        self._lane_free = [first_entry] * at_once  # when each lane may take its next object
        self.scripted = bool(scripted)
        if scripted:
            self.passes = scripted

    def _lane(self, path: TimedPath, slot: int) -> TimedPath:
        """The path narrowed into lane ``slot`` (y scaled into its band; slower, never
        faster)."""
        if self.at_once == 1:
            return path
        width = (_Y1 - _Y0) / self.at_once
        lo = _Y0 + slot * width + LANE_MARGIN
        y = lo + (path.xy[:, 1] - _Y0) * ((width - 2 * LANE_MARGIN) / (_Y1 - _Y0))
        return TimedPath(path.t, np.column_stack([path.xy[:, 0], y]))

    def _extend(self, t: float) -> None:
        if self.scripted:
            return  # the script's objects, and no more
        while not self.passes or self.passes[-1].entered <= t:
            kind = str(self.rng.choice(self.kinds))
            path = random_path(kind, self.rng, self.speed, self.acceleration)
            if self.at_once == 1:
                p = ObjectPass(len(self.passes) + 1, kind, self._next_entry, path)
                self._next_entry = max(p.entered + self.arrival_interval, p.left + self.gap)
            else:
                slot = int(np.argmin(self._lane_free))
                entry = max(self._next_entry, self._lane_free[slot])
                p = ObjectPass(len(self.passes) + 1, kind, entry, self._lane(path, slot), slot)
                self._lane_free[slot] = p.left + self.gap
                self._next_entry = entry + self.arrival_interval / self.at_once
            self.passes.append(p)

    def passes_at(self, t: float) -> list[ObjectPass]:
        """Every object on the table at ``t``."""
        self._extend(t)
        return [p for p in self.passes if p.entered <= t <= p.left]

    def slot_state(self, slot: int, t: float) -> tuple[int, ObjectState]:
        """The object in lane ``slot`` at ``t`` (its id, 0 and parked when the lane is
        empty)."""
        self._extend(t)
        for p in reversed(self.passes):
            if p.slot == slot and p.entered <= t <= p.left:
                return p.id, self._state_of(p, t)
        return 0, self._state_of(None, t)

    def pass_at(self, t: float) -> ObjectPass | None:
        """The object on the table at ``t``, if any."""
        self._extend(t)
        for p in reversed(self.passes):
            if p.entered <= t:
                return p if t <= p.left else None
        return None

    def state(self, t: float) -> ObjectState:
        """The object's state at ``t`` (parked out of view, not moving, when there is none)."""
        return self._state_of(self.pass_at(t), t)

    def _state_of(self, p: ObjectPass | None, t: float) -> ObjectState:
        if p is None:
            xy, v = PARKED, np.zeros(2)
        else:
            tau = t - p.entered
            xy, v = p.path.position(tau), p.path.velocity(tau)
            if self.position_error is not None:  # where the table really is
                xy = xy + self.position_error(float(xy[0]), float(xy[1]))
        moving = p is not None and 0.0 < t - p.entered < p.path.duration
        return object_state(self.model, xy, v, moving, p is not None)


def scripted_passes(
    script: Sequence[Mapping[str, Any]], speed: float = 0.02, acceleration: float = 0.02
) -> list[ObjectPass]:
    """The passes of a scripted stream (see :class:`ObjectStream`), in order of entry.

    Raises:
        ConfigError: for a bad entry, lane or path, or two objects in one lane at once.
    """
    passes = []
    for i, o in enumerate(sorted(script, key=lambda o: float(o.get('enter', math.nan)))):
        where = f'scripted object {i + 1}'
        enter, slot = float(o.get('enter', math.nan)), o.get('slot', 0)
        if not (math.isfinite(enter) and enter >= 0.0):
            raise ConfigError(f'{where}: enter must be a time >= 0 s, got {o.get("enter")!r}')
        if not (isinstance(slot, int) and 0 <= slot < MAX_AT_ONCE):
            raise ConfigError(f'{where}: slot must be a lane 0..{MAX_AT_ONCE - 1}, got {slot!r}')
        spec = o.get('path')
        if not isinstance(spec, Mapping) or spec.get('type') not in ('line', 'parabola'):
            raise ConfigError(f'{where}: path must be {{type: line|parabola, points: [...]}}')
        path = named_path(str(spec['type']), list(spec.get('points', ())), speed, acceleration)
        check_in_table(path.xy, where)
        passes.append(ObjectPass(i + 1, str(spec['type']), enter, path, slot))
    for a in passes:
        for b in passes:
            if a.id < b.id and a.slot == b.slot and b.entered <= a.left:
                raise ConfigError(
                    f'scripted objects {a.id} and {b.id} share lane {a.slot} at once'
                )
    return passes


def _script(text: str) -> list[Mapping[str, Any]]:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f'stream_script is not JSON: {exc}') from None
    if not isinstance(doc, list) or not all(isinstance(o, dict) for o in doc):
        raise ConfigError('stream_script must be a JSON list of objects')
    return doc


def table_from_parameters(p: Mapping[str, Any]) -> XYTable | ObjectStream:
    """The xy table of an ``xy_table`` node's parameters: one programmed path, or a stream.

    Raises:
        ConfigError: for a bad path or object model.
    """
    off = [float(v) for v in p['side_offset']]
    nrm = [float(v) for v in p['side_normal']]
    if len(off) != 3 or len(nrm) != 3:
        raise ConfigError('side_offset and side_normal need 3 numbers each')
    try:
        model = ObjectGeometry(
            float(p['top_height']), (off[0], off[1], off[2]), (nrm[0], nrm[1], nrm[2])
        )
    except GeometryError as exc:
        raise ConfigError(f'object: {exc}') from exc
    speed, accel = float(p['speed']), float(p['acceleration'])
    error = None
    if p.get('rig_file'):
        error = load_rig(str(p['rig_file'])).table_offset
    if p['path_type'] == 'stream':
        return ObjectStream(
            int(p['stream_seed']),
            float(p['arrival_interval']),
            float(p['start_time']),
            [str(k) for k in p['path_kinds']],
            speed=speed,
            acceleration=accel,
            model=model,
            position_error=error,
            at_once=int(p.get('objects_at_once', 1)),
            script=_script(str(p.get('stream_script') or '[]')),
        )
    path = named_path(
        str(p['path_type']), list(p['path_points']), speed, accel, str(p['csv_file'])
    )
    return XYTable(path, float(p['start_time']), model, error, bool(p.get('enters_at_start')))
