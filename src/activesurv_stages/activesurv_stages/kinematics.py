"""Stage axis kinematics: limits and time-optimal trapezoidal moves (the one motion model).

The controller emulators, the simulated stages and the dispatcher's reachability estimate all use
this module, so they agree on where an axis can be by when.

A move goes from any state (position p0, velocity v0) to rest at a goal, with |v| <= v_max and
|a| <= a_max, as a sequence of constant-acceleration segments. If the axis is moving away from
the goal, or too fast to stop before it, it first brakes to rest. It then accelerates towards
the goal, cruises at v_max if there is room, and brakes. Units are whatever the caller uses
consistently: SI (m or rad) in ROS, microsteps or machine units inside the emulators.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from activesurv_stages.errors import LimitError

_EPS = 1e-12


@dataclass(frozen=True)
class AxisLimits:
    """Limits of one axis.

    Attributes:
        min_position, max_position: soft travel limits.
        max_velocity: > 0 (a static axis is modelled by refusing goals, not by v = 0).
        max_acceleration: > 0.
        resolution: smallest commandable step (0: continuous).
    """

    min_position: float
    max_position: float
    max_velocity: float
    max_acceleration: float
    resolution: float = 0.0

    def __post_init__(self) -> None:
        vals = (
            self.min_position,
            self.max_position,
            self.max_velocity,
            self.max_acceleration,
            self.resolution,
        )
        if not all(math.isfinite(v) for v in vals):
            raise LimitError(f'axis limits must be finite, got {vals}')
        if self.min_position > self.max_position:
            raise LimitError(
                f'min_position {self.min_position} > max_position {self.max_position}'
            )
        if self.max_velocity <= 0 or self.max_acceleration <= 0 or self.resolution < 0:
            raise LimitError('max_velocity and max_acceleration must be > 0, resolution >= 0')

    def check_position(self, position: float, what: str = 'goal') -> float:
        """Return ``position`` (quantised to the resolution) or raise if outside the soft limits.

        Raises:
            LimitError: with the limits in the message.
        """
        if not math.isfinite(position):
            raise LimitError(f'{what} {position} is not a finite number')
        if self.resolution > 0:
            position = round(position / self.resolution) * self.resolution
        tol = max(self.resolution * 0.5, 1e-12)
        if position < self.min_position - tol or position > self.max_position + tol:
            raise LimitError(
                f'{what} {position:.6g} is outside the soft limits '
                f'[{self.min_position:.6g}, {self.max_position:.6g}]'
            )
        return min(max(position, self.min_position), self.max_position)

    def check_velocity(self, velocity: float | None) -> float:
        """A velocity limit for a move: ``None`` or 0 means the axis maximum; larger is clamped.

        Raises:
            LimitError: for a negative or non-finite value.
        """
        if velocity is None or velocity == 0.0:
            return self.max_velocity
        if not math.isfinite(velocity) or velocity < 0.0:
            raise LimitError(f'velocity limit {velocity} must be a finite number >= 0')
        return min(velocity, self.max_velocity)


@dataclass(frozen=True)
class Segment:
    duration: float
    acceleration: float


@dataclass(frozen=True)
class Move:
    """A planned move: constant-acceleration segments from (p0, v0), starting at ``t0``."""

    t0: float
    p0: float
    v0: float
    segments: tuple[Segment, ...]
    goal: float

    @property
    def duration(self) -> float:
        return sum(s.duration for s in self.segments)

    @property
    def end_time(self) -> float:
        return self.t0 + self.duration

    def state(self, t: float) -> tuple[float, float]:
        """(position, velocity) at ``t`` (before t0: the start; after: at rest at the goal)."""
        if t <= self.t0:
            return self.p0, self.v0
        p, v, tau = self.p0, self.v0, t - self.t0
        for seg in self.segments:
            dt = min(tau, seg.duration)
            p += v * dt + 0.5 * seg.acceleration * dt * dt
            v += seg.acceleration * dt
            tau -= dt
            if tau <= 0.0:
                return p, v
        return self.goal, 0.0


def _from_rest_or_towards(
    p: float,
    v: float,
    goal: float,
    v_max: float,
    a_max: float,
) -> list[Segment]:
    """Segments from (p, v), with v pointing to the goal and room to stop, to rest at goal."""
    s = 1.0 if goal >= p else -1.0
    dist = abs(goal - p)
    vs = s * v  # >= 0 here
    segs: list[Segment] = []
    if vs > v_max + _EPS:  # the limit was lowered mid-move: brake to v_max first
        dt = (vs - v_max) / a_max
        dist -= (vs * vs - v_max * v_max) / (2 * a_max)
        segs.append(Segment(dt, -s * a_max))
        vs = v_max
    v_peak_sq = a_max * dist + 0.5 * vs * vs
    if v_peak_sq < vs * vs:
        # Within rounding of the goal but still moving: brake to rest (overshoot < 1e-12).
        segs.append(Segment(vs / a_max, -s * a_max))
        return [seg for seg in segs if seg.duration > _EPS]
    if v_peak_sq <= v_max * v_max:
        v_peak = math.sqrt(max(v_peak_sq, 0.0))
        segs.append(Segment(max(v_peak - vs, 0.0) / a_max, s * a_max))
        segs.append(Segment(v_peak / a_max, -s * a_max))
    else:
        d_acc = (v_max * v_max - vs * vs) / (2 * a_max)
        d_dec = v_max * v_max / (2 * a_max)
        segs.append(Segment((v_max - vs) / a_max, s * a_max))
        segs.append(Segment(max(dist - d_acc - d_dec, 0.0) / v_max, 0.0))
        segs.append(Segment(v_max / a_max, -s * a_max))
    return [seg for seg in segs if seg.duration > _EPS]


def plan_move(t0: float, p0: float, v0: float, goal: float, v_max: float, a_max: float) -> Move:
    """Time-optimal move from (p0, v0) at t0 to rest at ``goal``.

    Raises:
        LimitError: for non-finite inputs or non-positive limits.
    """
    if not all(math.isfinite(x) for x in (t0, p0, v0, goal, v_max, a_max)):
        raise LimitError('move parameters must be finite')
    if v_max <= 0 or a_max <= 0:
        raise LimitError('v_max and a_max must be > 0')
    if abs(goal - p0) < 4 * _EPS and abs(v0) < _EPS:
        return Move(t0, p0, v0, (), goal)  # already there (same threshold as min_travel_time)
    segs: list[Segment] = []
    p, v = p0, v0
    s = 1.0 if goal >= p else -1.0
    stopping = v * v / (2 * a_max)
    if (v != 0.0 and s * v < 0.0) or (s * v > 0.0 and stopping > abs(goal - p) + 1e-12):
        # Moving away, or cannot stop in time: brake to rest first.
        dt = abs(v) / a_max
        a = -math.copysign(a_max, v)
        p += v * dt + 0.5 * a * dt * dt
        segs.append(Segment(dt, a))
        v = 0.0
    segs += _from_rest_or_towards(p, v, goal, v_max, a_max)
    return Move(t0, p0, v0, tuple(segs), goal)


def stop_move(t0: float, p0: float, v0: float, a_max: float) -> Move:
    """Brake to rest as fast as allowed (a controller's ``stop``)."""
    if v0 == 0.0:
        return Move(t0, p0, 0.0, (), p0)
    dt = abs(v0) / a_max
    a = -math.copysign(a_max, v0)
    goal = p0 + v0 * dt + 0.5 * a * dt * dt
    return Move(t0, p0, v0, (Segment(dt, a),), goal)


def min_travel_time(distance: float, v_max: float, a_max: float) -> float:
    """Time to travel ``distance`` from rest to rest (the dispatcher's reachability estimate)."""
    d = abs(distance)
    if d < 4 * _EPS:
        return 0.0
    if d <= v_max * v_max / a_max:
        return 2.0 * math.sqrt(d / a_max)
    return d / v_max + v_max / a_max


def reachable_distance(time: float, v_max: float, a_max: float) -> float:
    """How far an axis at rest can get and stop within ``time`` (inverse of min_travel_time)."""
    if time <= 0.0:
        return 0.0
    t_ramp = v_max / a_max
    if time <= 2 * t_ramp:
        return a_max * time * time / 4.0
    return v_max * (time - t_ramp)


class AxisSimulator:
    """One simulated axis: follows moves, refuses goals outside its limits, can be stopped."""

    def __init__(self, limits: AxisLimits, position: float = 0.0, t: float = 0.0) -> None:
        self.limits = limits
        start = limits.check_position(position, 'initial position')
        self.move = Move(t, start, 0.0, (), start)

    def state(self, t: float) -> tuple[float, float]:
        return self.move.state(t)

    def busy(self, t: float) -> bool:
        return t < self.move.end_time

    def command(self, t: float, goal: float, velocity: float | None = None) -> Move:
        """Start a move to ``goal`` now (checked against the soft limits first).

        Raises:
            LimitError: if the goal is outside the soft limits or the velocity is invalid.
        """
        g = self.limits.check_position(goal)
        v_max = self.limits.check_velocity(velocity)
        p, v = self.state(t)
        self.move = plan_move(t, p, v, g, v_max, self.limits.max_acceleration)
        return self.move

    def stop(self, t: float) -> Move:
        p, v = self.state(t)
        self.move = stop_move(t, p, v, self.limits.max_acceleration)
        return self.move

    def set_position(self, t: float, position: float) -> None:
        """Teleport (homing or a controller reset): at rest at ``position``."""
        self.move = Move(t, position, 0.0, (), position)
