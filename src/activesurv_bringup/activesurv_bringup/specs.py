"""Node specs shared by every kind of run: a camera's mount parameters, its imager, a simulated
stage, the live view, a real stage's bridge and a real camera's driver. Graph runs, hardware runs,
commissioning, replay and the lab all start these nodes."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from activesurv_common.trigger import SourceKind, Trigger
from activesurv_dispatch.sensors import Sensor
from activesurv_hardware.hardware_file import CameraEntry
from activesurv_launch.launcher import NodeSpec


def mount_parameters(sensor: Sensor) -> dict[str, Any]:
    m = sensor.mount
    axis = m.linear_axis if m.linear_axis is not None else [0.0, 0.0, 0.0]
    return {
        'mount.base': [float(v) for v in m.base],
        'mount.yaw_offset': float(m.yaw_offset),
        'mount.pitch': float(m.pitch),
        'mount.offset': [float(v) for v in m.offset],
        'mount.linear_axis': [float(v) for v in axis],
    }


def imager_spec(
    sensor: Sensor,
    told: Mapping[str, Any],
    sim_time: bool,
    extra: Mapping[str, Any] | None = None,
    remappings: Mapping[str, str] | None = None,
) -> NodeSpec:
    """The imager of one camera, as every route starts it: what it is told (an
    :class:`~activesurv_imaging.capture.ImagerConfig`'s parameters, or a recorded run's), its
    camera's mount, its clock, and what the route adds (``extra``: reliable images, recorded
    frames, a driver's trigger service, commissioned intrinsics)."""
    return NodeSpec(
        f'{sensor.camera_id}_imager',
        'activesurv_imaging.imager_node',
        parameters={'use_sim_time': sim_time, **told, **mount_parameters(sensor), **(extra or {})},
        remappings=dict(remappings or {}),
    )


def stage_spec(
    sensor: Sensor, initial: Any, motion_class: str, publish_rate: float, sim_time: bool
) -> NodeSpec:
    """The simulated stage of one camera: its joints, soft limits and start positions."""
    return NodeSpec(
        f'{sensor.camera_id}_stage',
        'activesurv_sim.sim_stage_node',
        parameters={
            'use_sim_time': sim_time,
            'camera_id': sensor.camera_id,
            'joints': list(sensor.joint_names),
            'kinds': (['linear'] if sensor.has_linear else []) + ['rotary'],
            'min': [lim.min_position for lim in sensor.limits],
            'max': [lim.max_position for lim in sensor.limits],
            'initial': [float(v) for v in initial],
            'motion_class': motion_class,
            'publish_rate': float(publish_rate),
        },
    )


def live_view_spec(port: int, sim_time: bool = True) -> NodeSpec:
    """The Foxglove live view on ``port`` (``--foxglove``)."""
    return NodeSpec(
        'live_view',
        'activesurv_liveview.live_view_node',
        parameters={'port': int(port), 'use_sim_time': sim_time},
    )


def bridge_spec(stage: str, config_file: str, home: bool, promise_hold: float = 0.0) -> NodeSpec:
    """A stage's bridge (``promise_hold``: the dispatcher's ``capture_hold``)."""
    return NodeSpec(
        f'{stage}_bridge',
        'activesurv_stages.stage_bridge_node',
        parameters={
            'config_file': config_file,
            'camera_id': stage,
            'home_on_connect': bool(home),
            'reconnect_period': 0.5,
            'promise_hold': float(promise_hold),
        },
    )


def source_specs(cam: CameraEntry, calibration: str) -> tuple[list[NodeSpec], dict[str, str]]:
    """A camera's driver node (``device:``) or, for a driver's topic, the imager's remappings."""
    cid = cam.camera_id
    if cam.source.kind == SourceKind.TOPIC:
        remap = {f'{cid}/image_raw': cam.source.value}
        return [], {**remap, f'{cid}/camera_info': cam.source.camera_info}
    options = dict(cam.source.options)
    return [
        NodeSpec(
            f'{cid}_camera',
            'activesurv_hardware.camera_node',
            parameters={
                'camera_id': cid,
                'device': cam.source.value,
                'width': int(options.get('width', 0)),
                'height': int(options.get('height', 0)),
                'fps': float(options.get('fps', cam.frame_rate)),
                'fourcc': str(options.get('fourcc', '')),
                'frame_rate': cam.frame_rate,
                'loop': bool(options.get('loop', False)),
                'camera_info_file': f'{calibration}/{cid}.yaml',
                'trigger': 'software' if cam.trigger == Trigger.SOFTWARE else 'free',
                'exposure_delay': cam.exposure_delay,
            },
        )
    ], {}
