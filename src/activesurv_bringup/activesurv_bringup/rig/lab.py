"""``activesurv lab``: an emulated lab, to try ``commission --live`` without hardware.

A lab that commissions its rig runs, on one ROS domain: a ``stage_bridge`` node per stage
controller (the xy table on a GRBL controller, each dynamic camera's stages on a Zaber daisy
chain), a camera driver per camera publishing ``<cam>/image_raw`` and ``camera_info`` when a
``capture_request`` names it, and the checkerboards on the table's carriage. ``activesurv lab``
runs exactly that, with the controllers emulated on pseudo-terminals
(:mod:`activesurv_stages.emulators`, the same emulators the serial tests use) and the cameras
simulated from a rig file (they render what the stage positions the bridges report show).
``activesurv commission --live`` then talks to it as it would to the real rig: it knows only
the topics.

::

    activesurv lab --rig RIG.yaml --out LABDIR [--cameras cam1,cam3]   # until Ctrl-C
    activesurv commission --live --out CALDIR --cameras cam1,cam3

Controller units: Zaber devices at 1 um (linear) or 1 urad (rotary) per microstep, homed at
the soft limit's minimum; GRBL in mm. Speeds are Table I's (``hardware`` motion class).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import yaml

from activesurv_bringup.files import new_output_dir
from activesurv_bringup.rig.commission import TABLE_RANGE, camera_spec, check_cameras
from activesurv_bringup.rig.rigs import nominal
from activesurv_dispatch.sensors import Sensor, Setup
from activesurv_launch.launcher import Launcher, NodeSpec
from activesurv_sim.conversions import TABLE_ID, TABLE_JOINTS
from activesurv_stages.config import motion_class
from activesurv_stages.emulators import (
    EmulatorBase,
    GrblAxisSpec,
    GrblEmulator,
    ZaberDeviceSpec,
    ZaberEmulator,
)

UNIT = 1e-6  # SI per Zaber microstep (m or rad)


def _axis(joint: str, axis: str, kind: str, lo: float, hi: float, si_per_unit: float) -> Any:
    v, a = motion_class('hardware').limits(kind)
    return {
        'joint': joint,
        'axis': axis,
        'kind': kind,
        'si_per_unit': si_per_unit,
        'offset': lo,
        'min': lo,
        'max': hi,
        'max_velocity': v,
        'max_acceleration': a,
    }


def table_controller(port: Path) -> tuple[GrblEmulator, dict[str, Any]]:
    """The xy table on an emulated GRBL controller (X, Y in mm) and its bridge config."""
    hw = motion_class('hardware')
    specs, axes = [], []
    for letter, joint, (lo, hi) in zip('XY', TABLE_JOINTS, TABLE_RANGE, strict=True):
        specs.append(GrblAxisSpec(letter, 1e3 * (hi - lo), 60e3 * hw.linear_velocity, 1e3))
        axes.append(_axis(joint, letter, 'linear', lo, hi, 1e-3))
    emu = GrblEmulator(port, specs, homing_time=0.1)
    return emu, {'controller': {'protocol': 'grbl', 'port': str(port), 'poll_rate': 20.0},
                 'axes': axes}  # fmt: skip


def camera_controller(sensor: Sensor, port: Path) -> tuple[ZaberEmulator, dict[str, Any]]:
    """One camera's stages as a Zaber daisy chain (device 1, 2, ... per joint) and its config."""
    kinds = (['linear'] if sensor.has_linear else []) + ['rotary']
    devices, axes = [], []
    for i, (joint, kind, lim) in enumerate(
        zip(sensor.joint_names, kinds, sensor.limits, strict=True), start=1
    ):
        v, a = motion_class('hardware').limits(kind)
        travel = round((lim.max_position - lim.min_position) / UNIT)
        name = 'X-LSM200A' if kind == 'linear' else 'X-RSW60A'
        devices.append(ZaberDeviceSpec(i, (0, travel), v / UNIT, a / UNIT, name=name))
        axes.append(_axis(joint, str(i), kind, lim.min_position, lim.max_position, UNIT))
    emu = ZaberEmulator(port, devices)
    return emu, {'controller': {'protocol': 'zaber', 'port': str(port), 'poll_rate': 20.0},
                 'axes': axes}  # fmt: skip


def _bridge(name: str, camera_id: str, config: dict[str, Any], out: Path) -> NodeSpec:
    path = out / f'{name}.yaml'
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return NodeSpec(
        f'{name}_bridge',
        'activesurv_stages.stage_bridge_node',
        parameters={
            'config_file': str(path),
            'camera_id': camera_id,
            'reconnect_period': 0.5,
            'home_on_connect': True,  # the lab's own emulated controllers: homing is harmless
        },
    )


def start_controllers(
    setup: Setup, cameras: Sequence[str], out: Path
) -> tuple[list[EmulatorBase], list[NodeSpec]]:
    """Emulated controllers on pseudo-terminals under ``out/dev`` and their bridge nodes."""
    dev = out / 'dev'
    dev.mkdir(parents=True, exist_ok=True)
    emu, cfg = table_controller(dev / 'ttyTABLE')
    emulators: list[EmulatorBase] = [emu]
    specs = [_bridge(TABLE_ID, TABLE_ID, cfg, out)]
    for s in setup.sensors:
        if s.camera_id in cameras:
            e, cfg = camera_controller(s, dev / f'tty{s.camera_id.upper()}')
            emulators.append(e)
            specs.append(_bridge(s.camera_id, s.camera_id, cfg, out))
    return emulators, specs


def lab_specs(rig_file: Path, setup: Setup, cameras: Sequence[str], out: Path) -> list[NodeSpec]:
    """The simulated cameras (the overhead one and ``cameras``) of the rig, on the wall clock,
    with nominal factory calibrations as their drivers would ship."""

    factory = out / 'factory'
    nominal().truth().save(factory)
    specs = [camera_spec('overhead', rig_file, factory, {'camera_type': 'overhead'})]
    for i, s in enumerate(setup.sensors):
        if s.camera_id in cameras:
            specs.append(camera_spec(s.camera_id, rig_file, factory, {'seed': 500 + i}))
    return specs


def run_lab(
    rig_file: Path,
    out: Path,
    cameras: Sequence[str] | None = None,
    progress: Callable[[str], None] = print,
    stop: threading.Event | None = None,
) -> None:
    """Run the emulated lab until ``stop`` is set, SIGINT or SIGTERM.

    Raises:
        ConfigError: for unknown cameras or an existing ``out``; NodeDiedError: if a node
            dies (its log is under ``out/logs``).
    """
    from activesurv_dispatch.sensors import load_setup

    setup = load_setup(motion='fast')
    chosen = check_cameras(setup, cameras)
    new_output_dir(out)
    stop = stop or threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    emulators, bridges = start_controllers(setup, chosen, out)
    launcher = Launcher(
        [*bridges, *lab_specs(rig_file, setup, chosen, out)],
        workdir=out / 'logs',
        env=dict(os.environ),
    )
    try:
        launcher.start()
        progress(
            f'lab up: xy table on GRBL ({out / "dev" / "ttyTABLE"}), '
            f'{", ".join(chosen)} on Zaber, cameras {["overhead", *chosen]}; Ctrl-C to stop'
        )
        while not stop.wait(0.5):
            launcher.check()  # NodeDiedError if a node died
    finally:
        launcher.stop()
        for e in emulators:
            e.close()
        time.sleep(0.1)
        progress('lab stopped')
