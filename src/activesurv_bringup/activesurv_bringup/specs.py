"""Node specs shared by every kind of run: a camera's mount parameters, a simulated stage, the
live view. Graph runs, commissioning, replay and the lab all start these nodes."""

from __future__ import annotations

from typing import Any

from activesurv_dispatch.sensors import Sensor
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
