"""Stage bridge round trip: a StageGoal in -> the first JointState showing motion out.

The ``stage_bridge`` node drives an emulated Zaber controller on a pseudo-terminal (50 Hz poll),
in this process over DDS; 20 goals, median and 90th percentile in ms. This is the latency the
motion submodule adds on top of the stage's own motion time.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

GOALS = 20


def _config(port: Path) -> dict[str, Any]:
    axis = {
        'si_per_unit': 1e-6,
        'max_acceleration': 0.5,
    }
    return {
        'controller': {'protocol': 'zaber', 'port': str(port), 'poll_rate': 50.0},
        'axes': [
            {
                **axis,
                'joint': 'cam1_x',
                'axis': '1',
                'kind': 'linear',
                'offset': -0.15,
                'min': -0.15,
                'max': 0.15,
                'max_velocity': 0.05,
            },
            {
                **axis,
                'joint': 'cam1_yaw',
                'axis': '2',
                'kind': 'rotary',
                'offset': -1.5,
                'min': -1.5,
                'max': 1.5,
                'max_velocity': 0.2,
            },
        ],
    }


def run() -> dict[str, object]:
    import rclpy
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from activesurv_common.ros import qos, topics
    from activesurv_interfaces.msg import StageGoal
    from activesurv_stages.emulators import ZaberDeviceSpec, ZaberEmulator
    from activesurv_stages.stage_bridge_node import StageBridgeNode

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    tmp = Path(tempfile.mkdtemp(prefix='bench_stages_'))
    emu = ZaberEmulator(
        tmp / 'ttyZ',
        [
            ZaberDeviceSpec(1, (0, 300_000), 300_000, 3e6),
            ZaberDeviceSpec(2, (0, 3_000_000), 3e6, 3e7),
        ],
    )
    (tmp / 'zaber.yaml').write_text(yaml.safe_dump(_config(tmp / 'ttyZ')))
    rclpy.init()
    bridge = StageBridgeNode(
        parameter_overrides=[Parameter('config_file', value=str(tmp / 'zaber.yaml'))]
    )
    peer = rclpy.create_node('bench_stages_peer')
    stream: list[tuple[float, float]] = []
    peer.create_subscription(
        JointState,
        topics.joint_states('cam1'),
        lambda m: stream.append((time.monotonic(), m.position[0])),
        qos.STATE,
    )
    pub = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)

    def spin_until(pred: Any, timeout: float = 15.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            rclpy.spin_once(bridge, timeout_sec=0.005)
            rclpy.spin_once(peer, timeout_sec=0.005)
            if pred():
                return True
        return False

    trips: list[float] = []
    try:
        if not spin_until(lambda: len(stream) > 3):
            raise RuntimeError('the bridge never published a joint state')
        target = -0.15
        for _ in range(GOALS):
            target += 0.005
            t0 = time.monotonic()
            p0 = stream[-1][1]
            pub.publish(
                StageGoal(joint_names=['cam1_x'], positions=[target], max_velocities=[0.0])
            )
            if spin_until(
                lambda t0=t0, p0=p0: stream[-1][0] > t0 and abs(stream[-1][1] - p0) > 1e-6
            ):
                trips.append(next(t for t, p in stream if t > t0 and abs(p - p0) > 1e-6) - t0)
            spin_until(lambda g=target: abs(stream[-1][1] - g) < 2e-6)
    finally:
        bridge.destroy_node()
        peer.destroy_node()
        rclpy.try_shutdown()
        emu.close()
    ms = sorted(1e3 * t for t in trips)
    return {
        'bridge_round_trip_ms': round(statistics.median(ms), 1),
        'bridge_round_trip_p90_ms': round(ms[int(0.9 * (len(ms) - 1))], 1),
        'bridge_goals_moved': f'{len(trips)}/{GOALS}',
    }
