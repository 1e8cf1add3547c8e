"""Node tests: sim_stage limits on its JointState stream, xy_table + sim_stage on simulated time,
and stage_bridge driving an emulated Zaber controller end to end."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_interfaces.msg import StageGoal
from activesurv_sim.sim_stage_node import SimStageNode
from activesurv_stages.emulators import ZaberDeviceSpec, ZaberEmulator
from activesurv_stages.stage_bridge_node import StageBridgeNode


def _goal(joints: list[str], positions: list[float], velocities: list[float] | None = None) -> Any:
    from activesurv_interfaces.msg import StageGoal

    return StageGoal(
        joint_names=joints, positions=positions, max_velocities=velocities or [0.0] * len(joints)
    )


def _zaber_config(tmp_path: Path, rotary: bool) -> None:
    """``tmp_path/zaber.yaml``: cam1's stages (1 um, 1 urad per microstep) on the emulator at
    ``tmp_path/ttyZ``; its linear axis alone unless ``rotary``."""
    axes = [
        {'joint': 'cam1_x', 'axis': '1', 'kind': 'linear', 'si_per_unit': 1e-6,
         'offset': -0.15, 'min': -0.15, 'max': 0.15, 'max_velocity': 0.05,
         'max_acceleration': 0.5},
        {'joint': 'cam1_yaw', 'axis': '2', 'kind': 'rotary', 'si_per_unit': 1e-6,
         'offset': -1.5, 'min': -1.5, 'max': 1.5, 'max_velocity': 0.2,
         'max_acceleration': 0.8},
    ]  # fmt: skip
    cfg = {
        'controller': {'protocol': 'zaber', 'port': str(tmp_path / 'ttyZ'), 'poll_rate': 50.0},
        'axes': axes if rotary else axes[:1],
    }
    (tmp_path / 'zaber.yaml').write_text(yaml.safe_dump(cfg))


def test_sim_stage_stream_respects_limits(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import JointState

    from activesurv_interfaces.msg import StageGoal

    stage = SimStageNode(
        parameter_overrides=[
            Parameter('motion_class', value='fast'),
            Parameter('publish_rate', value=100.0),
        ]
    )
    peer = rclpy_context.create_node('sim_stage_test_peer')
    stream: list[tuple[float, float, float]] = []

    def on_js(msg: JointState) -> None:
        t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        stream.append((t, msg.position[0], msg.position[1]))

    try:
        peer.create_subscription(JointState, topics.joint_states('cam1'), on_js, qos.STATE)
        pub = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
        assert spin_until([stage, peer], lambda: len(stream) > 5)
        pub.publish(_goal(['cam1_x', 'cam1_yaw'], [0.1, -0.6]))
        assert spin_until(
            [stage, peer],
            lambda: abs(stream[-1][1] - 0.1) < 1e-9 and abs(stream[-1][2] + 0.6) < 1e-9,
            timeout=15.0,
        )
        s = np.array(stream)
        t = s[:, 0]
        for col, v_max, a_max in ((1, 0.025, 0.10), (2, 0.2, 0.8)):
            v = np.diff(s[:, col]) / np.diff(t)
            assert np.max(np.abs(v)) <= v_max * 1.01
            # The second divided difference over unevenly spaced samples: the slopes of two
            # neighbouring intervals differ by at most a_max times the distance between the
            # intervals' midpoints, (t[i+2] - t[i]) / 2, for any spacing (a loaded machine's
            # stamps are uneven; dividing by the second interval alone read 2.7x a_max).
            a = np.diff(v) / ((t[2:] - t[:-2]) / 2.0)
            assert np.max(np.abs(a)) <= a_max * 1.01 + 1e-3, np.max(np.abs(a))
        # Out of the soft limits or for an unknown joint: refused, nothing moves.
        pub.publish(_goal(['cam1_x', 'nope'], [0.5, 0.0]))
        n = stage.counts['refused']
        assert spin_until([stage, peer], lambda: stage.counts['refused'] >= n + 2)
        assert abs(stream[-1][1] - 0.1) < 1e-9
    finally:
        stage.destroy_node()
        peer.destroy_node()


def test_static_system_does_not_move(rclpy_context: Any, spin_until: Callable[..., bool]) -> None:
    from activesurv_interfaces.msg import StageGoal

    stage = SimStageNode(
        parameter_overrides=[
            Parameter('motion_class', value='static'),
            Parameter('initial', value=[0.02, 0.3]),
        ]
    )
    peer = rclpy_context.create_node('static_test_peer')
    try:
        pub = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
        pub.publish(_goal(['cam1_x'], [0.1]))
        assert spin_until([stage, peer], lambda: stage.counts['refused'] >= 1)
        assert 'static system' in stage.last_refusal
        assert stage.axes['cam1_x'].state(1e12)[0] == pytest.approx(0.02)
    finally:
        stage.destroy_node()
        peer.destroy_node()


def test_a_goal_stamped_on_another_clock_moves_no_stage(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """A latched goal of another run (commissioning's, on the wall clock, heard by a run on
    simulated time) is refused by its stamp; a goal of this clock is followed."""
    from builtin_interfaces.msg import Time

    stage = SimStageNode(parameter_overrides=[Parameter('initial', value=[0.02, 0.3])])
    peer = rclpy_context.create_node('stale_goal_test_peer')
    try:
        pub = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
        old = _goal(['cam1_x'], [0.1])
        old.header.stamp = Time(sec=int(stage._now()) - 3600)  # an hour off this clock
        pub.publish(old)
        assert spin_until([stage, peer], lambda: stage.counts['refused'] >= 1)
        assert 'another run' in stage.last_refusal
        assert stage.axes['cam1_x'].state(stage._now() + 10.0)[0] == pytest.approx(0.02)
        fresh = _goal(['cam1_x'], [0.05])
        fresh.header.stamp = peer.get_clock().now().to_msg()
        pub.publish(fresh)
        assert spin_until([stage, peer], lambda: stage.counts['accepted'] >= 1)
        assert stage.axes['cam1_x'].state(stage._now() + 10.0)[0] == pytest.approx(0.05)
    finally:
        stage.destroy_node()
        peer.destroy_node()


def test_stage_bridge_node_against_emulator(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import JointState

    from activesurv_interfaces.msg import StageGoal

    emu = ZaberEmulator(
        tmp_path / 'ttyZ',
        [
            ZaberDeviceSpec(1, (0, 300_000), 300_000, 3e6),
            ZaberDeviceSpec(2, (0, 3_000_000), 3e6, 3e7),
        ],
    )
    _zaber_config(tmp_path, rotary=True)
    bridge = StageBridgeNode(
        parameter_overrides=[
            Parameter('config_file', value=str(tmp_path / 'zaber.yaml')),
            Parameter('reconnect_period', value=0.2),
            Parameter('home_on_connect', value=True),  # the emulator starts unreferenced
        ]
    )
    peer = rclpy_context.create_node('bridge_test_peer')
    stream: list[tuple[float, float]] = []
    peer.create_subscription(
        JointState,
        topics.joint_states('cam1'),
        lambda m: stream.append((time.monotonic(), m.position[0])),
        qos.STATE,
    )
    pub = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
    round_trips = []
    try:
        assert spin_until([bridge, peer], lambda: len(stream) > 3, timeout=15.0)
        target = -0.15
        for _ in range(5):
            target += 0.01
            t0 = time.monotonic()
            start_pos = stream[-1][1]
            pub.publish(_goal(['cam1_x'], [target]))
            assert spin_until(
                [bridge, peer],
                lambda t0=t0, p0=start_pos: stream[-1][0] > t0 and abs(stream[-1][1] - p0) > 1e-6,
                timeout=10.0,
            )
            round_trips.append(
                next(t for t, p in stream if t > t0 and abs(p - start_pos) > 1e-6) - t0
            )
            assert spin_until(
                [bridge, peer], lambda g=target: abs(stream[-1][1] - g) < 2e-6, timeout=10.0
            )
        # Outside the soft limits: refused by the node, nothing written to the port.
        before = len(emu.received)
        pub.publish(_goal(['cam1_x'], [0.3]))
        assert spin_until([bridge, peer], lambda: bridge.refusals >= 1)
        assert not any(b'move abs' in line for line in emu.received[before:])
        # Stamped an hour off the bridge's clock (a latched goal of another run): refused.
        stale = _goal(['cam1_x'], [-0.1])
        stale.header.stamp.sec = int(time.time()) - 3600
        pub.publish(stale)
        assert spin_until([bridge, peer], lambda: bridge.refusals >= 2)
        assert not any(b'move abs' in line for line in emu.received[before:])
    finally:
        bridge.destroy_node()
        peer.destroy_node()
        emu.close()
    # Every goal moved the axis (the round-trip time itself is measured by bench_stages.py).
    assert len(round_trips) == 5


def test_stage_bridge_stop_service_and_estop(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """``~/stop`` stops a moving axis; the latched e-stop (raised before or while the bridge
    runs) stops it and refuses every goal, with the e-stop in the diagnostics; lowering it lets
    goals through again."""
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Bool
    from std_srvs.srv import Trigger

    from activesurv_interfaces.msg import StageGoal

    emu = ZaberEmulator(tmp_path / 'ttyZ', [ZaberDeviceSpec(1, (0, 300_000), 300_000, 3e6)])
    _zaber_config(tmp_path, rotary=False)
    bridge = StageBridgeNode(
        parameter_overrides=[
            Parameter('config_file', value=str(tmp_path / 'zaber.yaml')),
            Parameter('home_on_connect', value=True),
        ]
    )
    peer = rclpy_context.create_node('bridge_stop_peer')
    stream: list[tuple[float, float, float]] = []
    diags: list[dict[str, str]] = []
    peer.create_subscription(
        JointState,
        topics.joint_states('cam1'),
        lambda m: stream.append((time.monotonic(), m.position[0], m.velocity[0])),
        qos.STATE,
    )
    peer.create_subscription(
        DiagnosticArray,
        topics.DIAGNOSTICS,
        lambda m: diags.extend({kv.key: kv.value for kv in s.values} for s in m.status),
        qos.DIAGNOSTICS,
    )
    goals = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
    estop = peer.create_publisher(Bool, topics.ESTOP, qos.ESTOP)
    client = peer.create_client(Trigger, '/stage_bridge/stop')
    try:
        assert spin_until([bridge, peer], lambda: len(stream) > 3, timeout=15.0)
        goals.publish(_goal(['cam1_x'], [0.14], [0.02]))
        assert spin_until([bridge, peer], lambda: stream[-1][1] > -0.145, timeout=10.0)
        assert client.wait_for_service(timeout_sec=5.0)
        future = client.call_async(Trigger.Request())
        assert spin_until([bridge, peer], future.done, timeout=5.0)
        assert future.result().success
        n = len(stream)
        assert spin_until(
            [bridge, peer],
            lambda: len(stream) > n + 5 and abs(stream[-1][1] - stream[-5][1]) < 1e-9,
            timeout=5.0,
        )
        assert stream[-1][1] < 0.0  # far short of the goal

        # The e-stop: goals refused, nothing written to the port, the diagnostics say so.
        estop.publish(Bool(data=True))
        assert spin_until([bridge, peer], lambda: bridge.worker.estop, timeout=5.0)
        before = len(emu.received)
        goals.publish(_goal(['cam1_x'], [0.1]))
        assert spin_until([bridge, peer], lambda: bridge.refusals >= 1, timeout=5.0)
        assert not any(b'move abs' in line for line in emu.received[before:])
        assert spin_until(
            [bridge, peer],
            lambda: any(
                d.get('estop') == 'true' and d.get('standing_still') == 'true' for d in diags
            ),
            timeout=5.0,
        )
        estop.publish(Bool(data=False))
        assert spin_until([bridge, peer], lambda: not bridge.worker.estop, timeout=5.0)
        goals.publish(_goal(['cam1_x'], [-0.14]))
        assert spin_until([bridge, peer], lambda: abs(stream[-1][1] + 0.14) < 2e-6, timeout=10.0)
    finally:
        bridge.destroy_node()
        peer.destroy_node()
        emu.close()


def test_sim_stage_states_of_an_instant_are_published_once(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """On a capture request the stage publishes its state at the instant ahead (from its
    profile); at the instant it publishes nothing more unless a later goal changed it."""
    from sensor_msgs.msg import JointState

    from activesurv_common.ros.conversions import sec_to_time
    from activesurv_interfaces.msg import CaptureRequest, StageGoal

    stage = SimStageNode(parameter_overrides=[Parameter('publish_rate', value=2.0)])
    peer = rclpy_context.create_node('sim_stage_instant_peer')
    got: list[tuple[float, float, float, float]] = []  # (stamp, received, x, yaw)

    def on_js(msg: JointState) -> None:
        t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        got.append((t, time.time(), msg.position[0], msg.position[1]))

    try:
        peer.create_subscription(JointState, topics.joint_states('cam1'), on_js, qos.STATE)
        req = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS)
        goal = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
        assert spin_until([stage, peer], lambda: len(got) > 0 and req.get_subscription_count())
        for moved in (False, True):
            t = round(time.time() + 0.6, 3)
            req.publish(CaptureRequest(demand_instant=sec_to_time(t), camera_ids=['cam1']))
            assert spin_until([stage, peer], lambda t=t: any(s == t for s, *_ in got))
            if moved:  # a goal after the request: the instant's state is published again
                goal.publish(_goal(['cam1_x', 'cam1_yaw'], [0.01, 0.05]))
                assert spin_until([stage, peer], lambda t=t: sum(s == t for s, *_ in got) >= 2)
            spin_until([stage, peer], lambda t=t: time.time() > t + 0.3, timeout=2.0)
            at_t = [g for g in got if g[0] == t]
            assert all(r < t for _, r, *_ in at_t), 'a state of the instant came at it'
            assert len(at_t) == (2 if moved else 1)
        # The last one is where the new profile has the axes at the instant.
        where = [stage.axes[j].state(t)[0] for j in ('cam1_x', 'cam1_yaw')]
        assert at_t[-1][2:] == pytest.approx(where, abs=1e-12)
        assert at_t[0][2:] != pytest.approx(where, abs=1e-6)
    finally:
        stage.destroy_node()
        peer.destroy_node()
