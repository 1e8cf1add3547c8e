"""A run on a real rig: the same node graph with stage bridges and camera drivers in place of
the simulator, on the wall clock.

What changes against a simulated run (:func:`~activesurv_bringup.experiments.graph.graph_specs`):

* every node runs on the wall clock (no ``/clock``, no ``use_sim_time``) in the rig's namespace;
  run time 0 is ``origin`` (wall seconds since the epoch), chosen a margin after the start so
  that the stages and the table are in place before the object moves;
* each camera's stages are a ``stage_bridge`` on its controller (the hardware file's YAML); its
  frames come from a ROS 2 driver's topic (remapped to the imager) or from our ``camera`` node
  (``device:``); its imager is told the trigger, frame rate and exposure delay;
* the xy table is a ``stage_bridge`` too, and ``table_runner`` streams the experiment's path to
  it and publishes what it reports as ``object_state`` (the truth, as the paper measured it);
  without a table controller nothing is truth, and the results say so;
* the recorder records the namespace's topics under their plain names (bags read alike).
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import yaml
from sensor_msgs.msg import JointState

from activesurv_bringup.errors import NodeDiedError
from activesurv_bringup.experiments.experiment import Experiment
from activesurv_bringup.experiments.graph import (
    Progress,
    RunMonitor,
    core_specs,
    locator_spec,
    run_graph,
)
from activesurv_bringup.experiments.options import RunOptions
from activesurv_bringup.specs import bridge_spec, imager_spec, source_specs
from activesurv_common.calibration import pose_to_list
from activesurv_common.ros import qos, topics
from activesurv_common.trigger import SourceKind, Trigger
from activesurv_dispatch.sensors import setup_to_dict
from activesurv_hardware.hardware_file import CameraEntry, Hardware
from activesurv_imaging.imager_config import ImagerConfig
from activesurv_interfaces.msg import StageGoal
from activesurv_launch.launcher import NodeSpec
from activesurv_recording.run_record import OnRig, RunRecord
from activesurv_sim.xytable import TABLE_ID

START_MARGIN = 25.0  # s from the launch to run time 0 at least: nodes up, stages in place
START_CPU_S = 3.0  # s of one core a node process takes to start on a busy machine (imports,
# DDS, an imager's compiled kernels), measured on a 2-core machine beside the lab


def start_margin(processes: int, cores: int | None = None) -> float:
    """Seconds from the launch to run time 0 for ``processes`` node processes: 10 s to place
    the stages plus their start shared over the cores (at most 8 counted), and at least
    :data:`START_MARGIN` (16 processes on 2 cores: 34 s; on 4 or more: 25 s)."""
    n = max(1, min(cores or os.cpu_count() or 1, 8))
    return max(START_MARGIN, 10.0 + START_CPU_S * processes / n)


def hardware_files(exp: Experiment, hw: Hardware, out: Path) -> dict[str, str]:
    """The believed set-up, the calibration and each controller's YAML under ``out/rig``."""
    assert exp.rig is not None
    d = out / 'rig'
    (d / 'controllers').mkdir(parents=True, exist_ok=True)
    exp.rig.calibration.save(d / 'calibration')
    (d / 'setup.yaml').write_text(yaml.safe_dump(setup_to_dict(exp.setup), sort_keys=False))
    files = {'calibration': str(d / 'calibration'), 'setup_file': str(d / 'setup.yaml')}
    stages = {cid: c.stages_dict for cid, c in hw.cameras.items()}
    stages[TABLE_ID] = hw.table_dict
    for cid, doc in stages.items():
        if doc is not None:
            path = d / 'controllers' / f'{cid}.yaml'
            path.write_text(yaml.safe_dump(dict(doc), sort_keys=False))
            files[f'controller:{cid}'] = str(path)
    return files


def imager_config(
    cam: CameraEntry, marker_radius: float, motion_correction: bool = True
) -> ImagerConfig:
    """What an imager on the real rig is told: its camera's trigger and timing."""
    return ImagerConfig(
        cam.camera_id,
        marker_radius,
        trigger=cam.trigger,
        frame_tolerance=_exposure_reach(cam),
        frame_rate=cam.frame_rate,
        exposure_delay=cam.exposure_delay,
        # Free-running frames arrive up to half a period plus the delay after the instant.
        frame_timeout=1.0 + cam.exposure_delay + (1.0 / cam.frame_rate),
        motion_correction=motion_correction,
    )


# s: how late a software trigger's exposure may land. The service call crosses DDS to a driver
# that may be busy (on the lab, 2 cores: 7 of 30 exposures 5.5-10.7 ms after the instant); a
# late frame is taken and moved to the instant along the predicted velocity, as a free-running
# camera's is, not refused.
SOFTWARE_TRIGGER_REACH = 0.02
HARDWARE_TRIGGER_REACH = 0.005  # s: a hardware trigger's exposure and its stamp's jitter


def _exposure_reach(cam: CameraEntry) -> float:
    """The largest |exposure - instant| the camera's frame may show (its imager's
    ``frame_tolerance``; free-running cameras use their frame period instead)."""
    if cam.trigger == Trigger.SOFTWARE and cam.source.kind == SourceKind.DEVICE:
        # Our camera node, software-triggered, answers with the frame nearest the instant:
        # within half a period of it (plus the stamps' jitter), moved there for the motion.
        return 0.5 / cam.frame_rate + 0.005
    if cam.trigger == Trigger.SOFTWARE:
        return SOFTWARE_TRIGGER_REACH
    return HARDWARE_TRIGGER_REACH


def capture_hold(hw: Hardware) -> float:
    """How long past a demand instant the rig's cameras stay still: as far as the frame
    nearest the instant may lie after it: half a frame period and the stamps' jitter for a
    free-running camera, or a driver we trigger in software by choosing among its streamed
    frames; a software trigger's reach for a driver's service; 0 when every camera exposes at
    the instant (hardware triggers)."""
    return max(
        (
            0.5 / cam.frame_rate + 0.005 if cam.trigger == Trigger.FREE else _exposure_reach(cam)
            for cam in hw.cameras.values()
            if cam.trigger != Trigger.HARDWARE
        ),
        default=0.0,
    )


def on_rig(exp: Experiment, hw: Hardware, origin: float, motion_correction: bool) -> OnRig:
    """What the run record says of a run on the rig ``hw`` with run time 0 at ``origin``."""
    return OnRig(
        hardware=str(hw.path),
        name=hw.name,
        namespace=hw.namespace,
        time_origin=origin,
        truth='table controller' if hw.table is not None else None,
        # What each imager was told, so that a replay of the recorded frames measures alike.
        imagers={
            cid: imager_config(cam, exp.setup.marker_radius, motion_correction).to_parameters()
            for cid, cam in hw.cameras.items()
        },
    )


def _recorder(
    hw: Hardware, bag: Path, image_rate: float, record: RunRecord, record_frames: str
) -> NodeSpec:
    """The recorder of a hardware run: the namespace's topics under their plain names."""
    return NodeSpec(
        'recorder',
        'activesurv_recording.recorder_node',
        parameters={
            'use_sim_time': False,
            'output': str(bag),
            'image_rate': float(image_rate),
            'run_info': record.to_json(),
            'strip_namespace': hw.namespace,
            # Free-running cameras stream 30 frames a second each: the bag keeps the overhead
            # stream thinned and no dynamic camera's frames (the observations, annotations and
            # stage states say what each imaged; 2.3 MB/s otherwise).
            'thin_topics': [
                '/overhead/image_raw',
                '/overhead/camera_info',
                hw.overhead.source.value,
            ],
            'exclude': ['/rosout', '/parameter_events']
            + (
                []
                if record_frames == 'all'
                else [f'/{cid}/image_raw' for cid in hw.cameras]
                + [c.source.value for c in hw.cameras.values()]
            ),
        },
    )


def hardware_specs(
    exp: Experiment,
    hw: Hardware,
    bag: Path,
    origin: float,
    image_rate: float = 2.0,
    home: bool = False,
    motion_correction: bool = True,
    record_frames: str = 'used',
    record: RunRecord | None = None,
) -> list[NodeSpec]:
    """Every node of a run on the rig ``hw``, in start order (the table runner last).

    ``record``: the run's record (default: the experiment's); the rig's facts are added.

    ``record_frames``: ``used`` records each frame an imager measured for a demand (PNG, on
    ``<cam>/demand_frame``), ``all`` every frame of every dynamic camera, ``none`` none.
    """
    wall: dict[str, Any] = {'use_sim_time': False}
    files = hardware_files(exp, hw, bag.parent)
    over = pose_to_list(exp.overhead(truth=False)[1])
    on = on_rig(exp, hw, origin, motion_correction)
    record = (record or exp.record()).with_hardware(on)
    specs = [_recorder(hw, bag, image_rate, record, record_frames)]
    sources, remap = source_specs(hw.overhead, files['calibration'])
    specs += sources
    locator = locator_spec(exp, wall, over, hw.geometry.top_marker_radius, remap)
    if (
        hw.overhead.source.kind == SourceKind.TOPIC
    ):  # the commissioned intrinsics, not the driver's
        intrinsics = Path(files['calibration'], 'overhead.yaml')
        parameters = {**locator.parameters, 'camera_info_file': str(intrinsics)}
        locator = replace(locator, parameters=parameters) if intrinsics.is_file() else locator
    specs.append(locator)
    believed = {'setup_file': files['setup_file']}
    times = [origin + float(t) for t in exp.demand_times]
    hold = capture_hold(hw)
    specs += core_specs(exp, wall, believed, over, times, bag.parent / 'logs', hold)
    for s in exp.setup.sensors:
        cid = s.camera_id
        cam = hw.cameras[cid]
        specs.append(bridge_spec(cid, files[f'controller:{cid}'], home, hold))
        sources, remap = source_specs(cam, files['calibration'])
        specs += sources
        commissioned = Path(files['calibration'], f'{cid}.yaml')
        specs.append(
            imager_spec(
                s,
                imager_config(cam, exp.setup.marker_radius, motion_correction).to_parameters(),
                sim_time=False,
                remappings=remap,
                extra={
                    'record_frames': record_frames == 'used',
                    # A software-triggered driver: its Trigger service, called ahead.
                    'trigger_service': cam.software_trigger[0],
                    'trigger_lead': cam.software_trigger[1],
                    # The commissioned intrinsics (and response: camera_info carries none),
                    # whatever the driver's camera_info says.
                    **({'camera_info_file': str(commissioned)} if commissioned.is_file() else {}),
                },
            )
        )
    if hw.table is not None:
        specs.append(bridge_spec(TABLE_ID, files[f'controller:{TABLE_ID}'], home))
    specs = [_in(hw.namespace, spec) for spec in specs]
    specs.append(_in(hw.namespace, table_runner_spec(exp, origin, hw.table is not None)))
    return specs


def table_runner_spec(exp: Experiment, origin: float, run_path: bool) -> NodeSpec:
    """The table runner: the path on the controller (``run_path``), its reports as truth."""
    params: dict[str, Any] = {
        **exp.table_config().to_parameters(),
        'run_path': run_path,
        'time_origin': float(origin),
    }
    params.pop('enters_at_start')  # a real table's object is on it from the start
    return NodeSpec('table_runner', 'activesurv_hardware.table_runner_node', parameters=params)


def _in(namespace: str, spec: NodeSpec) -> NodeSpec:
    if not namespace:
        return spec
    return NodeSpec(
        spec.name,
        spec.module,
        namespace,
        spec.parameters,
        spec.remappings,
        spec.required,
        spec.host,
        spec.members,
    )


def initial_goals(exp: Experiment) -> Sequence[tuple[str, Sequence[str], Sequence[float]]]:
    """Each camera's stage goal to its initial pose (placed before the object moves)."""
    return [
        (s.camera_id, list(s.joint_names), [float(v) for v in exp.setup.initial[s.camera_id]])
        for s in exp.setup.sensors
    ]


def place_cameras(exp: Experiment, origin: float, timeout: float = 20.0) -> Any:
    """``before_start`` of a hardware run: every camera to its initial pose, before run time 0
    (the paper placed them there before each experiment; a static system never moves them)."""

    def place(monitor: RunMonitor, progress: Progress) -> None:
        first: dict[str, JointState] = {}  # each camera's first joint state: has it moved since?
        taken: set[str] = set()  # cameras the dispatcher already drives (pre-positioning)
        goals = initial_goals(exp)
        ours = {cid: list(q) for cid, _, q in goals}
        states = monitor.states

        def on_goal(cid: str, m: StageGoal) -> None:
            if any(abs(a - b) > 1e-9 for a, b in zip(m.positions, ours[cid], strict=False)):
                taken.add(cid)

        def on_state(cid: str, m: JointState) -> None:
            first.setdefault(cid, m)

        monitor.watch_stages(ours, on_state)
        goal_subs = [
            monitor.node.create_subscription(
                StageGoal, topics.goal(cid), functools.partial(on_goal, cid), qos.GOAL
            )
            for cid in ours
        ]
        for cid, names, q in goals:
            monitor.send_goal(cid, names, q)

        def moved(cid: str) -> bool:
            a, b = first.get(cid), states.get(cid)
            return a is not None and b is not None and list(a.position) != list(b.position)

        def astray() -> list[str]:
            """The cameras not at their initial pose, each with where it is (a camera the
            dispatcher already drives, and whose controller obeys, is not waited for: the
            object is in view before run time 0 and its first demand's cameras go there)."""
            out = []
            for cid, names, q in goals:
                m = states.get(cid)
                if m is None:
                    out.append(f'{cid} (no joint state)')
                    continue
                if cid in taken and moved(cid):
                    continue
                at = dict(zip(m.name, m.position, strict=False))
                now = [at.get(n, math.inf) for n in names]
                if any(abs(a - v) > 1e-3 for a, v in zip(now, q, strict=True)):
                    out.append(f'{cid} (at {[round(a, 4) for a in now]}, not {list(q)})')
            return out

        deadline = time.monotonic() + timeout
        while astray() and time.monotonic() < deadline:
            monitor.spin(0.1)
        left = origin - time.time()
        missing = astray()
        # Placed: the run's monitor stops waking for every goal and every controller poll
        # (about 150 messages a second on the paper's rig: a sixth of a core).
        for sub in goal_subs:
            monitor.node.destroy_subscription(sub)
        monitor.unwatch_stages()
        progress(
            (f'cameras NOT all placed in time: {", ".join(missing)}' if missing else
             'cameras at their initial poses')
            + f'; run time 0 in {left:.1f} s'
        )  # fmt: skip
        if left < 2.0:
            hint = (
                ' (a controller not homed since power-up refuses every goal: add --home)'
                if missing
                else ''
            )
            when = (
                f'{-left:.1f} s past it' if left < 0.0 else f'{left:.1f} s before it, 2 s needed'
            )
            raise NodeDiedError(
                f'the rig came up too late for run time 0 ({when}): the stages or the table did '
                f'not answer in time, or this machine is too busy{hint}'
            )

    return place


def run_hardware(
    exp: Experiment,
    hw: Hardware,
    out_dir: Path,
    options: RunOptions,
    progress: Progress,
    home: bool = False,
    motion_correction: bool = True,
) -> Path:
    """Run ``exp`` on the rig ``hw`` (wall clock); returns the bag directory."""
    bag = out_dir / 'bag'
    out_dir.mkdir(parents=True, exist_ok=True)
    args = (options.image_rate, home, motion_correction, options.record_frames)
    processes = len(hardware_specs(exp, hw, bag, time.time(), *args))
    origin = time.time() + start_margin(processes)
    specs = hardware_specs(exp, hw, bag, origin, *args)
    opts = replace(options, time_origin=origin, namespace=hw.namespace, processes='nodes')
    progress(
        f'hardware run on {hw.name}: {len(specs)} nodes; run time 0 at wall '
        f'{time.strftime("%H:%M:%S", time.localtime(origin))}'
        + ('' if hw.table is not None else '; no table controller: no truth')
    )
    return run_graph(
        exp, out_dir, opts, progress, specs=specs, before_start=place_cameras(exp, origin)
    )
