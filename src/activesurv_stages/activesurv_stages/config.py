"""Axis configuration: SI <-> controller units, soft limits, and the paper's motion classes.

A controller YAML (``config/zaber_example.yaml``, ``config/grbl_example.yaml``)::

    controller: {protocol: zaber, port: /dev/ttyUSB0, baud: 115200, poll_rate: 20.0}
    axes:
      - joint: cam1_x          # ROS joint name (JointState)
        axis: "1"              # Zaber device number or GRBL letter
        kind: linear           # linear (m) or rotary (rad)
        si_per_unit: 4.7625e-8 # metres (or radians) per controller unit (microstep, mm, deg)
        offset: -0.15          # SI position at controller position 0
        min: -0.15             # soft limits, SI
        max: 0.15
        max_velocity: 0.025    # SI/s
        max_acceleration: 0.1  # SI/s^2

``SI = offset + si_per_unit * raw``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from activesurv_stages.errors import ConfigError, LimitError
from activesurv_stages.kinematics import AxisLimits
from activesurv_stages.schema import controller_problems

# libyaml's parser where PyYAML has it: the same safe subset, about ten times faster.
_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


@dataclass(frozen=True)
class MotionClass:
    """Velocity and acceleration caps of a camera system (paper Section IV-A).

    ``static`` cameras do not move; ``medium`` 10 mm/s and 0.1 rad/s; ``fast`` 25 mm/s and
    0.2 rad/s. The paper gives no accelerations: each axis reaches its cap in 0.25 s.
    """

    name: str
    linear_velocity: float
    rotary_velocity: float
    linear_acceleration: float
    rotary_acceleration: float

    @property
    def moves(self) -> bool:
        return self.linear_velocity > 0.0 or self.rotary_velocity > 0.0

    def limits(self, kind: str) -> tuple[float, float]:
        """(max velocity, max acceleration) for a ``linear`` or ``rotary`` axis."""
        if kind == 'linear':
            return self.linear_velocity, self.linear_acceleration
        if kind == 'rotary':
            return self.rotary_velocity, self.rotary_acceleration
        raise ConfigError(f'axis kind must be linear or rotary, got {kind!r}')


MOTION_CLASSES: dict[str, MotionClass] = {
    'static': MotionClass('static', 0.0, 0.0, 0.0, 0.0),
    'medium': MotionClass('medium', 0.010, 0.1, 0.04, 0.4),
    'fast': MotionClass('fast', 0.025, 0.2, 0.10, 0.8),
    # Table I's maxima (linear stages and xy table 0.3 m/s, rotary stages pi/6 rad/s), for
    # commissioning, where only the time taken matters.
    'hardware': MotionClass('hardware', 0.3, math.pi / 6.0, 1.2, 2.0 * math.pi / 3.0),
}


def motion_class(name: str) -> MotionClass:
    try:
        return MOTION_CLASSES[name]
    except KeyError as exc:
        raise ConfigError(
            f'unknown motion class {name!r}; choose from {sorted(MOTION_CLASSES)}'
        ) from exc


@dataclass(frozen=True)
class AxisConfig:
    """One axis of a controller, as ROS sees it (SI) and as the controller sees it (raw)."""

    joint: str
    axis: str
    kind: str
    si_per_unit: float
    offset: float
    limits: AxisLimits

    def __post_init__(self) -> None:
        if self.kind not in ('linear', 'rotary'):
            raise ConfigError(f'{self.joint}: kind must be linear or rotary, got {self.kind!r}')
        if not (math.isfinite(self.si_per_unit) and self.si_per_unit != 0.0):
            raise ConfigError(f'{self.joint}: si_per_unit must be finite and non-zero')
        if not math.isfinite(self.offset):
            raise ConfigError(f'{self.joint}: offset must be finite')

    def to_raw(self, si: float) -> float:
        return (si - self.offset) / self.si_per_unit

    def to_si(self, raw: float) -> float:
        return self.offset + self.si_per_unit * raw

    def speed_to_raw(self, si_per_s: float) -> float:
        return abs(si_per_s / self.si_per_unit)

    def checked_goal(self, position: float, velocity: float | None) -> tuple[float, float]:
        """(raw position, raw speed) of a goal that is inside the soft limits.

        Raises:
            LimitError: if the goal is outside the soft limits or not finite (nothing is sent).
        """
        p = self.limits.check_position(position, f'{self.joint} goal')
        v = self.limits.check_velocity(velocity)
        return self.to_raw(p), self.speed_to_raw(v)


@dataclass(frozen=True)
class ControllerConfig:
    protocol: str
    port: str
    baud: int
    poll_rate: float
    axes: tuple[AxisConfig, ...]

    def axis(self, joint: str) -> AxisConfig:
        for a in self.axes:
            if a.joint == joint:
                return a
        raise ConfigError(
            f'joint {joint!r} is not on this controller ({[a.joint for a in self.axes]})'
        )


def _axis_from_dict(d: dict[str, Any]) -> AxisConfig:
    try:
        limits = AxisLimits(
            float(d['min']),
            float(d['max']),
            float(d['max_velocity']),
            float(d['max_acceleration']),
        )
        return AxisConfig(
            str(d['joint']),
            str(d['axis']),
            str(d.get('kind', 'linear')),
            float(d['si_per_unit']),
            float(d.get('offset', 0.0)),
            limits,
        )
    except KeyError as exc:
        raise ConfigError(f'axis entry {d!r} is missing {exc}') from exc
    except (TypeError, ValueError, LimitError) as exc:
        raise ConfigError(f'axis entry {d!r}: {exc}') from exc


def controller_from_dict(data: dict[str, Any]) -> ControllerConfig:
    """Parse a controller configuration (checked by :mod:`activesurv_stages.schema`).

    Raises:
        ConfigError: naming every bad, missing or unknown key.
    """
    found = controller_problems(data)
    if found:
        raise ConfigError('; '.join(found))
    c = data['controller']
    try:
        protocol, port = str(c['protocol']), str(c['port'])
        baud, rate = int(c.get('baud', 115200)), float(c.get('poll_rate', 20.0))
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f'controller section: {exc!r}') from exc
    if not (math.isfinite(rate) and 0.5 <= rate <= 200.0):
        raise ConfigError(f'poll_rate must be in 0.5..200 Hz, got {rate}')
    axes = tuple(_axis_from_dict(a) for a in data['axes'])
    if not axes:
        raise ConfigError('a controller config needs at least one axis')
    joints = [a.joint for a in axes]
    if len(set(joints)) != len(joints):
        raise ConfigError(f'duplicate joint names: {joints}')
    return ControllerConfig(protocol, port, baud, rate, axes)


def load_controller(path: Path | str) -> ControllerConfig:
    try:
        data = yaml.load(Path(path).read_text(), Loader=_LOADER)
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f'cannot read controller config {path}: {exc}') from exc
    return controller_from_dict(data)
