"""``activesurv lab``: the whole rig emulated, for hardware mode without hardware.

A hardware-in-the-loop lab: the xy table on an emulated GRBL controller and each dynamic
camera's stages on an emulated Zaber daisy chain, all on pseudo-terminals under ``LAB/dev``
(:mod:`activesurv_stages.emulators`, the same emulators the serial tests use); and a camera
driver process per camera (``lab_camera``) that free-runs on the wall clock (30 Hz by default,
the overhead camera 10 Hz), publishes best effort with an exposure and read-out delay, jitter
and the occasional dropped frame, and renders the rig file's truth at the positions the
controllers report. The table carries the commissioning boards, or the object while a run
reports it. ``LAB/hardware.yaml`` describes the lab as a hardware file, written before the lab
reports ready; everything else (stage bridges, the graph) is started by the commands that use
the hardware, exactly as on a real rig::

    activesurv lab --rig RIG.yaml --out LAB                  # until Ctrl-C
    activesurv commission --live --hardware LAB/hardware.yaml --out CAL
    activesurv experiment --hardware LAB/hardware.yaml --calibration CAL --set A --system fast
        --out RUN

``--controller NAME=PORT`` (NAME ``table`` or a camera id) puts an external controller (a real
one on the bench, or an emulator that is not ours) in place of an emulated one; a ``table`` is a
GRBL controller with X and Y in mm (its ``$`` settings are left as found), a camera's a Zaber
chain (device 1 its linear stage if it has one, then its rotary stage).

Controller units: Zaber devices at 1 um (linear) or 1 urad (rotary) per microstep, homed at
the soft limit's minimum; GRBL in mm. Speeds are Table I's (``hardware`` motion class).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import yaml

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.files import new_output_dir
from activesurv_bringup.rig.commission import camera_spec, check_cameras
from activesurv_bringup.rig.hardware import paper_rig
from activesurv_bringup.rig.rigs import nominal
from activesurv_common.lifetime import STOP_SIGNALS
from activesurv_common.trigger import Trigger
from activesurv_dispatch.sensors import Sensor, Setup, load_setup
from activesurv_hardware.hardware_file import load_hardware
from activesurv_launch.launcher import Launcher, NodeSpec
from activesurv_sim.conversions import DRIVER_UP
from activesurv_sim.xytable import TABLE_ID, TABLE_JOINTS, TABLE_RANGE
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


TRIGGER_LEAD = 0.001  # s: a software trigger's service call, sent this much ahead
EXPOSURE_DELAY = 0.02  # s: the lab cameras' exposure and read-out, as the hardware file says
JITTER = 0.002  # s: std of their stamps around it
DROP_RATE = 0.01  # frames that never arrive
OVERHEAD_RATE = 10.0  # Hz


def start_controllers(
    setup: Setup, cameras: Sequence[str], out: Path, external: Mapping[str, str]
) -> tuple[list[EmulatorBase], dict[str, dict[str, Any]]]:
    """Emulated controllers on pseudo-terminals under ``out/dev`` (none for the stages named in
    ``external``: their config points at the given port); each stage's controller YAML."""
    dev = out / 'dev'
    dev.mkdir(parents=True, exist_ok=True)
    emulators: list[EmulatorBase] = []
    configs: dict[str, dict[str, Any]] = {}
    emu, cfg = table_controller(dev / 'ttyTABLE')
    configs[TABLE_ID] = _use(emu, cfg, external.get('table'), emulators)
    for s in setup.sensors:
        if s.camera_id in cameras:
            e, cfg = camera_controller(s, dev / f'tty{s.camera_id.upper()}')
            configs[s.camera_id] = _use(e, cfg, external.get(s.camera_id), emulators)
    return emulators, configs


def _use(
    emu: EmulatorBase, cfg: dict[str, Any], port: str | None, emulators: list[EmulatorBase]
) -> dict[str, Any]:
    if port is None:
        emulators.append(emu)
        return cfg
    emu.close()  # an external controller takes this stage's place
    return {**cfg, 'controller': {**cfg['controller'], 'port': port}}


def hardware_document(
    configs: Mapping[str, dict[str, Any]], rate: float, namespace: str, trigger: str = 'free'
) -> dict[str, Any]:
    """The lab as a hardware file (:mod:`activesurv_hardware.hardware_file`)."""
    rig = paper_rig('lab', namespace)
    ns = f'/{namespace.strip("/")}' if namespace.strip('/') else ''
    o = rig.object

    def camera(cid: str, hz: float) -> dict[str, Any]:
        doc: dict[str, Any] = {
            'source': {'topic': f'{ns}/{cid}/image_raw'},
            'trigger': 'free',
            'frame_rate': hz,
            'exposure_delay': EXPOSURE_DELAY,
        }
        if trigger == Trigger.SOFTWARE and cid != 'overhead':
            doc.update(
                trigger='software',
                trigger_service=f'{ns}/{cid}_camera/trigger',
                trigger_lead=TRIGGER_LEAD,
            )
        return doc

    return {
        'name': 'lab',
        'namespace': namespace,
        'calibration': 'calibration',
        'home': True,  # the emulated stages power up unreferenced, as real ones do
        'geometry': {
            'table': {'x': list(rig.table_x), 'y': list(rig.table_y)},
            'marker_radius': o.side_radius,
            'top_marker_radius': o.top_radius,
            'object': {
                'top_height': o.top_height,
                'side_offset': list(o.side_offset),
                'side_normal': list(o.side_normal),
            },
            'layout': 'paper',
        },
        'cameras': {
            cid: {**camera(cid, rate), 'stages': cfg}
            for cid, cfg in configs.items()
            if cid != TABLE_ID
        },
        'table': {'stages': configs[TABLE_ID]},
        'overhead': camera('overhead', OVERHEAD_RATE),
    }


def lab_specs(
    rig_file: Path,
    setup: Setup,
    cameras: Sequence[str],
    out: Path,
    rate: float,
    namespace: str,
    delays: Mapping[str, float] | None = None,
    offsets: Mapping[str, float] | None = None,
    trigger: str = 'free',
) -> list[NodeSpec]:
    """The lab's camera drivers (the overhead one and ``cameras``): free-running on the wall
    clock, best effort, with nominal factory calibrations as their drivers would ship.

    ``delays`` and ``offsets`` (camera id -> s): a camera's true exposure delay and its clock's
    offset, which the hardware file does not know (it says :data:`EXPOSURE_DELAY`)."""
    delays, offsets = dict(delays or {}), dict(offsets or {})

    def timing(cid: str) -> dict[str, float]:
        return {
            'exposure_delay': delays.get(cid, EXPOSURE_DELAY),
            'clock_offset': offsets.get(cid, 0.0),
        }

    factory = out / 'factory'
    nominal().truth().save(factory)
    lab = {
        'exposure_delay': EXPOSURE_DELAY,
        'jitter': JITTER,
        'drop_rate': DROP_RATE,
        'state_hold': 0.3,
    }
    specs = [
        camera_spec(
            'overhead',
            rig_file,
            factory,
            {
                **lab,
                'camera_type': 'overhead',
                'frame_rate': OVERHEAD_RATE,
                'seed': 499,
                **timing('overhead'),
            },
        )
    ]
    for i, s in enumerate(setup.sensors):
        if s.camera_id in cameras:
            extra = {**lab, 'frame_rate': rate, 'seed': 500 + i, **timing(s.camera_id)}
            extra['software_trigger'] = trigger == Trigger.SOFTWARE
            specs.append(camera_spec(s.camera_id, rig_file, factory, extra))
    return [
        replace(s, module='activesurv_sim.lab_camera_node', namespace=namespace) for s in specs
    ]


def camera_rates(logs: Path) -> list[str]:
    """The rate each lab camera achieved, from the last report in its log."""
    out = []
    for log in sorted(logs.glob('*_camera.log')):
        said = [ln for ln in log.read_text(errors='replace').splitlines() if ' Hz of ' in ln]
        if said:
            out.append(f'{log.stem.removesuffix("_camera")}: {said[-1].split("]: ")[-1]}')
    return out


def _cameras_streaming(logs: Path) -> bool:
    """Whether every camera driver of the lab is up (its log says so)."""
    cams = sorted(logs.glob('*_camera.log'))
    return bool(cams) and all(DRIVER_UP in log.read_text(errors='replace') for log in cams)


def run_lab(
    rig_file: Path,
    out: Path,
    cameras: Sequence[str] | None = None,
    progress: Callable[[str], None] = print,
    stop: threading.Event | None = None,
    controllers: Mapping[str, str] | None = None,
    frame_rate: float = 30.0,
    namespace: str = '',
    delays: Mapping[str, float] | None = None,
    offsets: Mapping[str, float] | None = None,
    trigger: str = 'free',
) -> Path:
    """Run the emulated lab until ``stop`` is set, SIGINT or SIGTERM; returns its hardware file.

    ``delays``, ``offsets``: cameras' true exposure delays and clock offsets (s), unknown to
    the hardware file the lab writes (it says :data:`EXPOSURE_DELAY` for every camera).

    Raises:
        ConfigError: for unknown cameras or an existing ``out``; NodeDiedError: if a camera
            driver dies (its log is under ``out/logs``).
    """
    setup = load_setup(motion='fast')
    chosen = check_cameras(setup, cameras)
    external = dict(controllers or {})
    unknown = sorted(set(external) - {'table', *chosen})
    if unknown:
        raise ConfigError(f'--controller {unknown}: NAME is table or one of {chosen}')
    for flag, given in (('--exposure-delay', delays), ('--clock-offset', offsets)):
        stray = sorted(set(given or {}) - {'overhead', *chosen})
        if stray:
            raise ConfigError(f'{flag} {stray}: NAME is overhead or one of {chosen}')
    new_output_dir(out)
    stop = stop or threading.Event()
    for sig in STOP_SIGNALS:
        signal.signal(sig, lambda *_: stop.set())
    emulators, configs = start_controllers(setup, chosen, out, external)
    hw_file = out / 'hardware.yaml'
    hw_file.write_text(
        '# activesurv lab: the emulated rig as a hardware file (activesurv lab wrote it)\n'
        + yaml.safe_dump(
            hardware_document(configs, frame_rate, namespace, trigger), sort_keys=False
        )
    )
    load_hardware(hw_file)  # what we wrote must read back
    launcher = Launcher(
        lab_specs(rig_file, setup, chosen, out, frame_rate, namespace, delays, offsets, trigger),
        workdir=out / 'logs',
        env=dict(os.environ),
    )
    try:
        launcher.start()
        where = ', '.join(f'{k}={v}' for k, v in external.items()) or 'none'
        progress(
            f'lab up: xy table on GRBL, {", ".join(chosen)} on Zaber (external: {where}); '
            f'cameras free-running at {frame_rate:g} Hz (overhead {OVERHEAD_RATE:g} Hz); '
            f'hardware file {hw_file}; Ctrl-C to stop'
        )
        ready = out / 'ready'
        while not stop.wait(0.2):
            launcher.check()  # NodeDiedError if a camera driver died
            if not ready.exists() and _cameras_streaming(out / 'logs'):
                ready.write_text('every camera driver is up\n')
                progress(f'lab ready: every camera driver is up ({ready})')
    finally:
        launcher.stop()
        for e in emulators:
            e.close()
        time.sleep(0.1)
        for line in camera_rates(out / 'logs'):
            progress(line)
        progress('lab stopped')
    return hw_file
