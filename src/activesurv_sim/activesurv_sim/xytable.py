"""The xy table and its preprogrammed paths (pure core).

The object rides on a 500 mm x 200 mm xy table (paper Table I) that follows a path unknown to
the surveillance system. A path is a polyline traversed at a constant path speed with
acceleration ramps (the kinematics core along the arc length), or a CSV of ``t, x, y`` that the
table follows as given once it has been checked against the table's range and speed. The table
only translates: the top marker is the carriage position at a fixed height, and the side marker
(the surveyed target) is a rigid offset from it with a fixed normal.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.object_geometry import ObjectGeometry
from activesurv_stages.errors import ConfigError
from activesurv_stages.kinematics import plan_move

Array = NDArray[np.float64]

TABLE_ID = 'xy_table'  # the table as a two-axis stage: xy_table/stage/goal, .../joint_states
TABLE_JOINTS = ('table_x', 'table_y')
TABLE_RANGE = ((0.0, 0.5), (0.0, 0.2))  # m (Table I)
TABLE_MAX_SPEED = 0.3  # m/s (Table I)


@dataclass(frozen=True)
class TimedPath:
    """Positions sampled densely in time; ``t`` from 0 (path start) to ``duration``."""

    t: Array
    xy: Array

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def position(self, t: float) -> Array:
        """Position at path time ``t`` (held at the ends)."""
        return np.array([np.interp(t, self.t, self.xy[:, 0]), np.interp(t, self.t, self.xy[:, 1])])

    def velocity(self, t: float, dt: float = 1e-3) -> Array:
        if t < 0.0 or t > self.duration:
            return np.zeros(2)
        a, b = max(t - dt, 0.0), min(t + dt, self.duration)
        return (self.position(b) - self.position(a)) / max(b - a, 1e-12)


def start_shortfall(heard: dict[str, int], wanted: dict[str, int]) -> str:
    """What simulated time still waits for: ``''`` when every topic has the subscribers it
    wants (``heard``/``wanted``: matched and expected subscribers per topic), else which do not,
    e.g. ``'/clock 7 of 9'``. The table holds time at 0 until then (or its timeout): a node
    whose /clock reader matched late stays at time 0 while the others run on (at rtf 3 a
    dispatcher at t = 0 for 8 simulated seconds lost seven demands)."""
    short = [f'{t} {heard.get(t, 0)} of {n}' for t, n in wanted.items() if heard.get(t, 0) < n]
    return ', '.join(short)


def near_instant(t: float, instants: Iterable[float], period: float) -> bool:
    """Whether a periodic state at ``t`` falls within a quarter ``period`` of a demand
    instant whose own state and tick are (or were) published: it is then skipped, as the
    instant's state serves for both, and every process wakes once, not twice, just when the
    cameras image."""
    return any(abs(t - tj) < 0.25 * period for tj in instants)


def check_in_table(xy: Array, what: str) -> None:
    (x0, x1), (y0, y1) = TABLE_RANGE
    bad = (
        (xy[:, 0] < x0 - 1e-9)
        | (xy[:, 0] > x1 + 1e-9)
        | (xy[:, 1] < y0 - 1e-9)
        | (xy[:, 1] > y1 + 1e-9)
    )
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ConfigError(
            f'{what} leaves the table ({x0}..{x1} m x {y0}..{y1} m) at point {i}: '
            f'({xy[i, 0]:.4f}, {xy[i, 1]:.4f})'
        )


def profiled(
    points: ArrayLike, speed: float, acceleration: float, samples: int = 4000
) -> TimedPath:
    """A polyline traversed at ``speed`` with ramps of ``acceleration`` at both ends.

    Raises:
        ConfigError: for fewer than 2 points, a path off the table, or bad speed/acceleration.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise ConfigError('a path needs at least two finite (x, y) points')
    if not (0.0 < speed <= TABLE_MAX_SPEED and acceleration > 0.0):
        raise ConfigError(f'speed must be in (0, {TABLE_MAX_SPEED}] m/s and acceleration > 0')
    check_in_table(pts, 'the path')
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0.0:
        raise ConfigError('the path has zero length')
    move = plan_move(0.0, 0.0, 0.0, float(s[-1]), speed, acceleration)
    ts = np.linspace(0.0, move.duration, samples)
    arc = np.array([move.state(t)[0] for t in ts])
    xy = np.column_stack([np.interp(arc, s, pts[:, 0]), np.interp(arc, s, pts[:, 1])])
    return TimedPath(ts, xy)


def line(
    start: ArrayLike, end: ArrayLike, speed: float = 0.02, acceleration: float = 0.02
) -> TimedPath:
    return profiled(np.array([start, end], dtype=np.float64), speed, acceleration)


def parabola(
    start: ArrayLike,
    apex: ArrayLike,
    end: ArrayLike,
    speed: float = 0.02,
    acceleration: float = 0.02,
    points: int = 400,
) -> TimedPath:
    """The parabola y = a x^2 + b x + c through ``start``, ``apex`` and ``end``.

    Raises:
        ConfigError: if the three x values are not distinct and increasing or decreasing.
    """
    p = np.array([start, apex, end], dtype=np.float64)
    if not (p[0, 0] < p[1, 0] < p[2, 0] or p[0, 0] > p[1, 0] > p[2, 0]):
        raise ConfigError('parabola points need distinct, ordered x values')
    coeffs = np.polyfit(p[:, 0], p[:, 1], 2)
    xs = np.linspace(p[0, 0], p[2, 0], points)
    return profiled(np.column_stack([xs, np.polyval(coeffs, xs)]), speed, acceleration)


def from_csv(path: Path | str, max_speed: float = TABLE_MAX_SPEED) -> TimedPath:
    """A ``t,x,y`` CSV (seconds, metres, world frame); times are shifted to start at 0.

    Raises:
        ConfigError: for a missing header, bad numbers, non-increasing times, points off the
            table, or speeds the table cannot reach.
    """
    try:
        with open(path, newline='') as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise ConfigError(f'cannot read trajectory {path}: {exc}') from exc
    if not rows or [c.strip() for c in rows[0]] != ['t', 'x', 'y']:
        raise ConfigError(f'{path}: the first line must be the header "t,x,y"')
    try:
        data = np.array([[float(v) for v in r] for r in rows[1:] if r], dtype=np.float64)
    except ValueError as exc:
        raise ConfigError(f'{path}: every row must be three numbers: {exc}') from exc
    if data.ndim != 2 or data.shape[1] != 3 or len(data) < 2:
        raise ConfigError(f'{path}: need at least two rows of t,x,y')
    if not np.all(np.isfinite(data)):
        raise ConfigError(f'{path}: NaN or infinite values')
    t = data[:, 0] - data[0, 0]
    if np.any(np.diff(t) <= 0.0):
        raise ConfigError(f'{path}: times must be strictly increasing')
    check_in_table(data[:, 1:], f'trajectory {path}')
    v = np.hypot(*np.diff(data[:, 1:], axis=0).T) / np.diff(t)
    if np.max(v) > max_speed + 1e-9:
        i = int(np.argmax(v))
        raise ConfigError(
            f'{path}: needs {v[i]:.3f} m/s at t={t[i]:.2f} s; the table reaches {max_speed} m/s'
        )
    return TimedPath(t, data[:, 1:].copy())


def write_csv(path: Path | str, timed: TimedPath, step: float = 0.05) -> None:
    """Save a path as ``t,x,y`` (e.g. to replay it with ``--trajectory``)."""
    ts = np.arange(0.0, timed.duration + 1e-9, step)
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['t', 'x', 'y'])
        for t in ts:
            x, y = timed.position(float(t))
            w.writerow([f'{t:.4f}', f'{x:.6f}', f'{y:.6f}'])


def object_state(
    geometry: ObjectGeometry, xy: Array, v: Array, moving: bool, present: bool = True
) -> ObjectState:
    """The object's state with its carriage at ``xy`` moving at ``v`` (m, m/s)."""
    top = np.array([xy[0], xy[1], geometry.top_height])
    return ObjectState(
        top, top + geometry.offset, geometry.normal, np.array([v[0], v[1], 0.0]), moving, present
    )


@dataclass(frozen=True)
class TableConfig:
    """What the xy table is told (the typed half of a run description): the object's path, its
    speed and start, and the markers on the carriage. The graph turns it into the simulated
    ``xy_table``'s (or a real table's ``table_runner``'s) parameters, lockstep into an
    :class:`XYTable`.

    Attributes:
        path_type: ``line``, ``parabola`` or ``csv``.
        path_points: the line's or parabola's points (m), as :func:`named_path` takes them.
        csv_file: the ``t,x,y`` file of a ``csv`` path.
        speed, acceleration: the path's speed (m/s) and acceleration (m/s^2).
        start_time: when the object starts (s).
        enters_at_start: out of every camera's view before ``start_time``.
        model: the markers on the carriage.
    """

    path_type: str
    path_points: tuple[float, ...] = ()
    csv_file: str = ''
    speed: float = 0.02
    acceleration: float = 0.02
    start_time: float = 0.5
    enters_at_start: bool = False
    model: ObjectGeometry = field(default_factory=ObjectGeometry)

    def path(self) -> TimedPath:
        """The object's path.

        Raises:
            ConfigError: for an unknown type, bad points or an unreadable CSV.
        """
        return named_path(
            self.path_type, self.path_points, self.speed, self.acceleration, self.csv_file
        )

    def table(self, position_error: Callable[[float, float], Array] | None = None) -> XYTable:
        """The object on the table (with the rig's table errors, if given)."""
        return XYTable(
            self.path(), self.start_time, self.model, position_error, self.enters_at_start
        )

    def to_parameters(self) -> dict[str, object]:
        """The ``xy_table`` node's parameters saying the same."""
        out: dict[str, object] = {
            'path_type': self.path_type,
            'speed': self.speed,
            'acceleration': self.acceleration,
            'start_time': self.start_time,
            'enters_at_start': self.enters_at_start,
            'top_height': self.model.top_height,
            'side_offset': list(self.model.side_offset),
            'side_normal': list(self.model.side_normal),
        }
        out['csv_file'] = self.csv_file
        if self.path_type != 'csv':  # (an empty array parameter has no type: left out)
            out['path_points'] = list(self.path_points)
        return out


@dataclass(frozen=True)
class ObjectState:
    top: Array
    side: Array
    side_normal: Array
    velocity: Array
    moving: bool
    present: bool = True  # False: no object on the table (a stream between two objects)


PARKED = np.array([100.0, 100.0])  # where an absent object is: in no camera's view


class XYTable:
    """The object on the table: at the path's first point until ``start_time``, then along it.

    With ``enters_at_start`` the object is not in the workspace before ``start_time`` (parked
    out of every camera's view): it enters, moving, at ``start_time``, as in the paper's
    experiments, so nothing can track it or dispatch for it before.
    """

    def __init__(
        self,
        path: TimedPath,
        start_time: float = 1.0,
        model: ObjectGeometry | None = None,
        position_error: Callable[[float, float], Array] | None = None,
        enters_at_start: bool = False,
    ) -> None:
        """``position_error(x, y)``: where the table really is minus where it is commanded
        (the rig's error map, :meth:`activesurv_sim.rig.Rig.table_offset`); None: exact."""
        if not math.isfinite(start_time):
            raise ConfigError('start_time must be finite')
        self.position_error = position_error
        self.enters_at_start = enters_at_start
        self.path = path
        self.start_time = start_time
        self.model = model or ObjectGeometry()
        n = np.asarray(self.model.side_normal, dtype=np.float64)
        self._normal = n / np.linalg.norm(n)

    @property
    def end_time(self) -> float:
        return self.start_time + self.path.duration

    def state(self, t: float) -> ObjectState:
        tau = t - self.start_time
        if tau < 0.0 and self.enters_at_start:
            return object_state(self.model, PARKED, np.zeros(2), False, present=False)
        xy = self.path.position(tau)
        if self.position_error is not None:
            xy = xy + self.position_error(float(xy[0]), float(xy[1]))
        v = self.path.velocity(tau)
        return object_state(self.model, xy, v, bool(0.0 <= tau <= self.path.duration))


def named_path(
    kind: str, points: Sequence[float], speed: float, acceleration: float, csv_file: str = ''
) -> TimedPath:
    """A path from node parameters: ``line`` [x0, y0, x1, y1], ``parabola`` [start, apex, end
    as 6 numbers], or ``csv`` (``csv_file``).

    Raises:
        ConfigError: for an unknown kind or the wrong number of points.
    """
    p = [float(v) for v in points]
    if kind == 'line':
        if len(p) != 4:
            raise ConfigError('a line needs 4 numbers: x0, y0, x1, y1')
        return line(p[:2], p[2:], speed, acceleration)
    if kind == 'parabola':
        if len(p) != 6:
            raise ConfigError('a parabola needs 6 numbers: start, apex and end (x, y each)')
        return parabola(p[:2], p[2:4], p[4:], speed, acceleration)
    if kind == 'csv':
        if not csv_file:
            raise ConfigError('path_type csv needs csv_file')
        return from_csv(csv_file)
    raise ConfigError(f'unknown path_type {kind!r}; use line, parabola or csv')
