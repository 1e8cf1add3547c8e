"""Reliability: NaN/inf and out-of-range values in messages over DDS (issue 8, point 4).

Each node gets garbage on its inputs from a peer and must (a) not die, (b) count or report it,
and (c) still do its job on the next good message. Stage nodes must never move outside their
soft limits, whatever the goal says.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

pytestmark = pytest.mark.node  # in-process rclpy nodes

NAN, INF = float('nan'), float('inf')


def _observation(cam: str, index: int, x: float, stamp: Any) -> Any:
    from activesurv_interfaces.msg import MarkerObservation

    m = MarkerObservation(camera_id=cam, demand_index=index, status=0)
    m.header.frame_id = 'world'
    m.header.stamp = stamp
    m.position.x, m.position.y, m.position.z = x, 0.1, 0.04
    m.normal.y = -1.0
    m.covariance = np.diag([1e-7] * 3 + [1e-5] * 3).reshape(-1).tolist()
    return m


def test_fusion_survives_nan_observations(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from activesurv_common.ros import qos, topics
    from activesurv_fusion.fusion_node import FusionNode
    from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, TargetEstimate

    fusion = FusionNode(parameter_overrides=[Parameter('collect_timeout', value=0.5)])
    peer = rclpy_context.create_node('bad_fusion_peer')
    got: list[TargetEstimate] = []
    try:
        req_pub = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS_LATCHED)
        obs_pub = peer.create_publisher(
            MarkerObservation, topics.MARKER_OBSERVATIONS, qos.EVENTS_LATCHED
        )
        peer.create_subscription(TargetEstimate, topics.TARGET_ESTIMATE, got.append, qos.RESULTS)
        assert spin_until(
            [fusion, peer],
            lambda: req_pub.get_subscription_count() > 0 and obs_pub.get_subscription_count() > 0,
        )
        stamp = fusion.get_clock().now().to_msg()
        req = CaptureRequest(demand_index=1, camera_ids=['cam1', 'cam2', 'cam3'])
        req.demand_instant = stamp
        req_pub.publish(req)
        bad_nan = _observation('cam1', 1, NAN, stamp)
        bad_inf = _observation('cam2', 1, 0.2, stamp)
        bad_inf.covariance = [INF] * 36
        obs_pub.publish(bad_nan)
        obs_pub.publish(bad_inf)
        obs_pub.publish(_observation('cam3', 1, 0.2, stamp))
        assert spin_until([fusion, peer], lambda: len(got) == 1, timeout=10.0)
        est = got[0]
        # The two bad readings are failures with a reason; the good one still gives a pose.
        assert est.status == TargetEstimate.STATUS_PARTIAL, est
        assert list(est.cameras_used) == ['cam3']
        assert 'invalid observation' in est.reason, est.reason
        assert math.isfinite(est.position.x)

        # The node keeps working on the next demand.
        stamp = fusion.get_clock().now().to_msg()
        req = CaptureRequest(demand_index=2, camera_ids=['cam1', 'cam2'])
        req.demand_instant = stamp
        req_pub.publish(req)
        obs_pub.publish(_observation('cam1', 2, 0.3, stamp))
        obs_pub.publish(_observation('cam2', 2, 0.3001, stamp))
        assert spin_until([fusion, peer], lambda: len(got) == 2, timeout=10.0)
        assert got[1].status == TargetEstimate.STATUS_OK
    finally:
        fusion.destroy_node()
        peer.destroy_node()


def test_dispatcher_survives_nan_horizon_and_joint_states(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import JointState

    from activesurv_common.ros import qos, topics
    from activesurv_dispatch.dispatcher_node import DispatcherNode
    from activesurv_interfaces.msg import DemandHorizon, DemandPoint

    node = DispatcherNode()
    peer = rclpy_context.create_node('bad_dispatch_peer')
    try:
        h_pub = peer.create_publisher(DemandHorizon, topics.DEMAND_HORIZON, qos.LATCHED)
        j_pub = peer.create_publisher(JointState, topics.joint_states('cam1'), qos.SENSOR)
        assert spin_until(
            [node, peer],
            lambda: h_pub.get_subscription_count() > 0 and j_pub.get_subscription_count() > 0,
        )
        for _ in range(5):
            j_pub.publish(JointState(name=['cam1_x', 'cam1_yaw'], position=[NAN, 0.0]))
            j_pub.publish(JointState(name=['cam1_x', 'cam1_yaw'], position=[INF, 0.0]))
        d = DemandPoint(index=0)
        d.pose.pose.position.x = NAN
        d.pose.pose.orientation.w = 1.0
        h_pub.publish(DemandHorizon(demands=[d]))
        assert spin_until(
            [node, peer],
            lambda: (
                node.session.counts['bad_joint_states'] >= 2
                and node.session.counts['bad_demands'] >= 1
            ),
        )
        assert 'cam1' not in node.session.joints, (
            'a NaN stage state was taken as the camera position'
        )
        assert node.session.demands == {} or all(
            np.all(np.isfinite(dm.position)) for dm in node.session.demands.values()
        )
        # Good state afterwards is accepted.
        j_pub.publish(JointState(name=['cam1_x', 'cam1_yaw'], position=[0.1, 0.2]))
        assert spin_until([node, peer], lambda: 'cam1' in node.session.joints)
        assert np.allclose(node.session.joints['cam1'], [0.1, 0.2])
    finally:
        node.destroy_node()
        peer.destroy_node()


def test_stage_never_leaves_its_soft_limits(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import JointState

    from activesurv_common.ros import qos, topics
    from activesurv_interfaces.msg import StageGoal
    from activesurv_sim.sim_stage_node import SimStageNode

    stage = SimStageNode(
        parameter_overrides=[
            Parameter('motion_class', value='fast'),
            Parameter('publish_rate', value=100.0),
        ]
    )
    peer = rclpy_context.create_node('bad_stage_peer')
    seen: list[list[float]] = []
    try:
        peer.create_subscription(
            JointState,
            topics.joint_states('cam1'),
            lambda m: seen.append(list(m.position)),
            qos.STATE,
        )
        pub = peer.create_publisher(StageGoal, topics.goal('cam1'), qos.GOAL)
        assert spin_until([stage, peer], lambda: len(seen) > 5)
        names = ['cam1_x', 'cam1_yaw']
        for pos, vel in (
            ([NAN, 0.0], [0.0, 0.0]),
            ([0.1, INF], [0.0, 0.0]),
            ([-5.0, 0.0], [0.0, 0.0]),
            ([0.1, 0.0], [NAN, 0.0]),
            ([0.1, 0.0], [-1.0, 0.0]),
        ):
            # The goal topic keeps only the latest goal: send one at a time.
            n = stage.counts['refused']
            pub.publish(
                StageGoal(joint_names=names[: len(pos)], positions=pos, max_velocities=vel)
            )
            assert spin_until([stage, peer], lambda n=n: stage.counts['refused'] > n), (pos, vel)
        pub.publish(StageGoal(joint_names=names, positions=[0.05, 0.3], max_velocities=[0.0, 0.0]))
        assert spin_until(
            [stage, peer],
            lambda: abs(seen[-1][0] - 0.05) < 1e-9 and abs(seen[-1][1] - 0.3) < 1e-9,
            timeout=15.0,
        )
        arr = np.array(seen)
        assert np.all(np.isfinite(arr))
        assert arr[:, 0].min() >= 0.0 - 1e-12
        assert arr[:, 0].max() <= 0.30 + 1e-12
    finally:
        stage.destroy_node()
        peer.destroy_node()
