"""Camera faults for reliability experiments: ``--fault CAMERA:KIND[:MAGNITUDE]``.

Kinds: ``bias`` (metres added to the camera's reported x, world frame), ``noise`` (metres of extra
Gaussian position noise, std), ``frozen`` (the camera keeps delivering its first image: a stuck
frame), ``dead`` (the camera's nodes are not running: no stage state, no observations), ``flip``
(the imager picks the wrong one of the two circle poses). CAMERA is cam1 ... cam4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from activesurv_bringup.errors import ConfigError


class FaultKind(StrEnum):
    """What goes wrong with a camera (the module docstring says how each is injected)."""

    BIAS = 'bias'
    NOISE = 'noise'
    FROZEN = 'frozen'
    DEAD = 'dead'
    FLIP = 'flip'


KINDS = tuple(k.value for k in FaultKind)
NEEDS_MAGNITUDE = (FaultKind.BIAS, FaultKind.NOISE)


@dataclass(frozen=True)
class Fault:
    camera: str
    kind: FaultKind
    magnitude: float = 0.0

    def __str__(self) -> str:
        return f'{self.camera}:{self.kind}:{self.magnitude:g}'


def parse_fault(text: str, cameras: tuple[str, ...] = ('cam1', 'cam2', 'cam3', 'cam4')) -> Fault:
    """Parse ``CAMERA:KIND[:MAGNITUDE]``.

    Raises:
        ConfigError: with what is wrong and what is allowed.
    """
    parts = text.split(':')
    if len(parts) not in (2, 3):
        raise ConfigError(
            f'fault {text!r}: expected CAMERA:KIND[:MAGNITUDE], e.g. cam2:bias:0.002'
        )
    cam, kind = parts[0], parts[1]
    if cam not in cameras:
        raise ConfigError(f'fault {text!r}: unknown camera {cam!r}; cameras are {list(cameras)}')
    if kind not in KINDS:
        raise ConfigError(f'fault {text!r}: unknown kind {kind!r}; kinds are {list(KINDS)}')
    magnitude = 0.0
    if len(parts) == 3:
        try:
            magnitude = float(parts[2])
        except ValueError as exc:
            raise ConfigError(f'fault {text!r}: magnitude {parts[2]!r} is not a number') from exc
        if not math.isfinite(magnitude):
            raise ConfigError(f'fault {text!r}: magnitude must be finite')
    if kind in NEEDS_MAGNITUDE and len(parts) != 3:
        raise ConfigError(f'fault {text!r}: {kind} needs a magnitude in metres')
    if kind == 'noise' and magnitude < 0:
        raise ConfigError(f'fault {text!r}: noise std must be >= 0')
    return Fault(cam, FaultKind(kind), magnitude)


@dataclass(frozen=True)
class Kill:
    """A node killed (SIGKILL) at simulated time ``at`` and, optionally, restarted later."""

    node: str
    at: float
    restart_at: float | None = None


KILLABLE = (
    'fusion',
    'predictor',
    'dispatcher',
    'recorder',
    'overhead_camera',
    'overhead_locator',
)


def parse_kill(text: str, cameras: tuple[str, ...] = ('cam1', 'cam2', 'cam3', 'cam4')) -> Kill:
    """Parse ``NODE@T[:RESTART]`` (simulated seconds), e.g. ``cam2_imager@3.5:6``.

    NODE is a node of the graph: ``fusion``, ``dispatcher``, ``predictor``, ``recorder``,
    ``overhead_camera``, ``overhead_locator`` or ``camN_imager``, ``camN_stage``, ``camN_camera``.

    Raises:
        ConfigError: with what is wrong and what is allowed.
    """
    node, sep, when = text.partition('@')
    per_camera = tuple(f'{c}_{n}' for c in cameras for n in ('imager', 'stage', 'camera'))
    if not sep:
        raise ConfigError(f'kill {text!r}: expected NODE@T[:RESTART], e.g. cam2_imager@3.5:6')
    if node not in KILLABLE + per_camera:
        raise ConfigError(
            f'kill {text!r}: unknown node {node!r}; nodes are {list(KILLABLE)} and '
            f'CAM_imager, CAM_stage, CAM_camera for CAM in {list(cameras)}'
        )
    parts = when.split(':')
    try:
        times = [float(p) for p in parts]
    except ValueError as exc:
        raise ConfigError(f'kill {text!r}: times must be numbers (simulated s)') from exc
    if len(times) > 2 or not all(math.isfinite(t) and t >= 0 for t in times):
        raise ConfigError(f'kill {text!r}: expected T or T:RESTART, finite and >= 0')
    if len(times) == 2 and times[1] <= times[0]:
        raise ConfigError(f'kill {text!r}: the restart must come after the kill')
    return Kill(node, times[0], times[1] if len(times) == 2 else None)


def imager_injection(fault: Fault | None) -> dict[str, float | bool]:
    """The imager's fault-injection settings for ``fault`` (parameter and config names alike)."""
    if fault is None:
        return {}
    if fault.kind is FaultKind.BIAS:
        return {'inject_bias_x': fault.magnitude}
    if fault.kind is FaultKind.NOISE:
        return {'inject_noise': fault.magnitude}
    if fault.kind is FaultKind.FLIP:
        return {'inject_flip': True}
    return {}
