"""The schema of a stage controller YAML (what ``stage_bridge`` reads), with pydantic.

::

    controller: {protocol: zaber, port: /dev/ttyUSB0, baud: 115200, poll_rate: 20.0}
    axes:
      - {joint: cam1_x, axis: '1', kind: linear, si_per_unit: 4.7625e-8, offset: 0.0,
         min: 0.0, max: 0.3, max_velocity: 0.3, max_acceleration: 1.2}

Every key is checked: unknown keys, enums (``protocol``, ``kind``), finite numbers in range,
standard baud rates, the protocol's axis ids (Zaber device numbers 1-99, GRBL letters), one
joint name per axis. :func:`controller_problems` returns every mistake at once.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any

from pydantic import Field, ValidationError, field_validator, model_validator

from activesurv_common.schema import StrictModel, problems


class Protocol(StrEnum):
    """The serial protocols the bridge speaks."""

    ZABER = 'zaber'
    GRBL = 'grbl'


class AxisKind(StrEnum):
    LINEAR = 'linear'
    ROTARY = 'rotary'


STANDARD_BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)
GRBL_LETTERS = 'XYZABC'
DAISY_CHAINED = (Protocol.ZABER,)
"""Protocols whose controllers share one port (Zaber devices on one daisy chain)."""


class ControllerSection(StrictModel):
    protocol: Protocol = Field(description='serial protocol: zaber (ASCII) or grbl (1.1)')
    port: str = Field(min_length=1, description='serial port, e.g. /dev/ttyUSB0')
    baud: int = Field(115200, description=f'baud rate, one of {STANDARD_BAUDS}')
    poll_rate: float = Field(20.0, ge=0.5, le=200.0, description='position polls per second [Hz]')

    @field_validator('baud')
    @classmethod
    def _standard(cls, v: int) -> int:
        if v not in STANDARD_BAUDS:
            raise ValueError(
                f'not a standard baud rate (one of {", ".join(map(str, STANDARD_BAUDS))})'
            )
        return v


class AxisSection(StrictModel):
    joint: str = Field(min_length=1, description='ROS joint name (JointState), e.g. cam1_x')
    axis: str | int = Field(description='Zaber device number (1-99) or GRBL letter (X, Y, ...)')
    kind: AxisKind = Field(description='linear (m) or rotary (rad); required')
    si_per_unit: float = Field(
        description='metres (or radians) per controller unit (microstep, mm, degree) [m or rad]'
    )
    offset: float = Field(0.0, description='SI position at controller position 0 [m or rad]')
    min: float = Field(description='lower soft limit [m or rad]')
    max: float = Field(description='upper soft limit [m or rad]')
    max_velocity: float = Field(gt=0.0, description='velocity cap [m/s or rad/s]')
    max_acceleration: float = Field(gt=0.0, description='acceleration cap [m/s^2 or rad/s^2]')

    @field_validator('si_per_unit')
    @classmethod
    def _nonzero(cls, v: float) -> float:
        if v == 0.0:
            raise ValueError('must be non-zero [m or rad per controller unit]')
        return v

    @model_validator(mode='after')
    def _limits(self) -> AxisSection:
        if self.min >= self.max:
            raise ValueError(
                f'{self.joint}: need min < max, got [{self.min}, {self.max}] m or rad'
            )
        return self


class ControllerFile(StrictModel):
    """A controller YAML: one controller and the axes it drives."""

    controller: ControllerSection
    axes: list[AxisSection] = Field(min_length=1)

    @model_validator(mode='after')
    def _axes(self) -> ControllerFile:
        joints = [a.joint for a in self.axes]
        if len(set(joints)) != len(joints):
            raise ValueError(f'duplicate joint names: {joints}')
        ids = [str(a.axis).strip() for a in self.axes]
        if len(set(ids)) != len(ids):
            raise ValueError(f'two joints on one axis: {ids}')
        for i, a in enumerate(ids):
            if self.controller.protocol is Protocol.ZABER and not (
                a.isdigit() and 1 <= int(a) <= 99
            ):
                raise ValueError(f'axes[{i}].axis: a Zaber device number 1-99, got {a!r}')
            if self.controller.protocol is Protocol.GRBL and a not in GRBL_LETTERS:
                raise ValueError(f'axes[{i}].axis: a GRBL axis letter ({GRBL_LETTERS}), got {a!r}')
        return self


def controller_problems(data: Any, prefix: str = '') -> list[str]:
    """Every mistake of a controller YAML document, one line each (empty: valid)."""
    if not isinstance(data, dict):
        return [f'{prefix or "controller file"}: a mapping with controller: and axes: is needed']
    try:
        ControllerFile.model_validate(data)
    except ValidationError as exc:
        return problems(exc, ControllerFile, prefix)
    return []
