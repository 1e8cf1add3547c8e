"""Node test: a DemandHorizon in; stage goals, a DispatchPlan and a CaptureRequest out."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_dispatch.dispatcher_node import DispatcherNode
from activesurv_dispatch.sensors import load_setup

pytestmark = pytest.mark.node  # in-process rclpy nodes


def test_horizon_to_goals_plan_and_capture(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import JointState

    from activesurv_interfaces.msg import (
        CaptureRequest,
        DemandHorizon,
        DemandPoint,
        DispatchPlan,
        StageGoal,
    )

    setup = load_setup(motion='fast')
    node = DispatcherNode(parameter_overrides=[Parameter('capture_lead', value=0.5)])
    peer = rclpy_context.create_node('dispatcher_test_peer')
    goals: dict[str, StageGoal] = {}
    plans: list[DispatchPlan] = []
    captures: list[CaptureRequest] = []
    for s in setup.sensors:
        peer.create_subscription(
            StageGoal,
            topics.goal(s.camera_id),
            lambda m, c=s.camera_id: goals.__setitem__(c, m),
            qos.LATCHED,
        )
    peer.create_subscription(DispatchPlan, topics.DISPATCH_PLAN, plans.append, qos.LATCHED)
    peer.create_subscription(CaptureRequest, topics.CAPTURE_REQUEST, captures.append, qos.EVENTS)
    js_pubs = {
        s.camera_id: peer.create_publisher(
            JointState, topics.joint_states(s.camera_id), qos.EVENTS
        )
        for s in setup.sensors
    }
    horizon_pub = peer.create_publisher(DemandHorizon, topics.DEMAND_HORIZON, qos.LATCHED)

    def publish_joints() -> None:
        for s in setup.sensors:
            js = JointState(
                name=list(s.joint_names), position=[float(v) for v in setup.initial[s.camera_id]]
            )
            js.header.stamp = peer.get_clock().now().to_msg()
            js_pubs[s.camera_id].publish(js)

    try:
        assert spin_until(
            [node, peer], lambda: (publish_joints(), len(node.session.joints) == 4)[1]
        )
        now = peer.get_clock().now().nanoseconds * 1e-9
        h = DemandHorizon(track_state=DemandHorizon.TRACK_CONFIRMED)
        for j in range(3):
            d = DemandPoint(index=j)
            t = now + 4.0 + j
            d.demand_instant.sec, d.demand_instant.nanosec = int(t), int((t % 1) * 1e9)
            d.pose.pose.position.x, d.pose.pose.position.y = 0.22 + 0.01 * j, 0.05
            d.pose.pose.position.z = 0.05
            d.pose.covariance = (
                np.diag([4e-6, 4e-6, 2.5e-7, 1e-4, 1e-4, 1e-4]).reshape(-1).tolist()
            )
            d.normal.y = -1.0
            h.demands.append(d)
        horizon_pub.publish(h)
        assert spin_until(
            [node, peer], lambda: (publish_joints(), bool(plans) and goals)[1], timeout=10.0
        )
        plan = plans[-1]
        roles = {a.camera_id: a.role for a in plan.assignments}
        assert sum(r == 1 for r in roles.values()) == 3  # k = 3 assigned
        assert plan.first_demand_index == 0
        assert plan.expected_fused_visibility > 0.0
        for cid, g in goals.items():
            lims = setup.sensor(cid).limits
            for p, lim in zip(g.positions, lims, strict=True):
                assert lim.min_position <= p <= lim.max_position
        # The capture request goes out capture_lead before the demand instant.
        assert spin_until(
            [node, peer], lambda: (publish_joints(), bool(captures))[1], timeout=10.0
        )
        c = captures[0]
        assert c.demand_index == 0
        assigned = sorted(a.camera_id for a in plan.assignments if a.role == 1)
        assert sorted(c.camera_ids) == assigned
        sent = peer.get_clock().now().nanoseconds * 1e-9
        t0 = c.demand_instant.sec + 1e-9 * c.demand_instant.nanosec
        assert t0 - sent <= 0.5 + 0.2
    finally:
        node.destroy_node()
        peer.destroy_node()


def test_dispatcher_rejects_bad_parameters(rclpy_context: Any) -> None:
    node = DispatcherNode()
    try:
        assert not node.set_parameters([Parameter('k', value=0)])[0].successful
        assert not node.set_parameters([Parameter('rho', value=-1.0)])[0].successful
        assert not node.set_parameters([Parameter('motion_class', value='warp')])[0].successful
    finally:
        node.destroy_node()
