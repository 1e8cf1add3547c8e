"""Node test: overhead fixes (PointStamped) -> predictor -> DemandHorizon and track over DDS."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import sec_to_time
from activesurv_prediction.predictor_node import PredictorNode

pytestmark = pytest.mark.node  # in-process rclpy nodes


def test_fixes_to_demand_horizon(rclpy_context: Any, spin_until: Callable[..., bool]) -> None:
    from activesurv_interfaces.msg import DemandHorizon

    pred = PredictorNode(
        parameter_overrides=[
            Parameter('demand_times', value=[10.0, 12.0, 14.0]),
            Parameter('confirm_fixes', value=5),
            Parameter('horizon', value=2),
            # The fixes carry made-up stamps (1-4 s) while the node runs on the wall clock.
            Parameter('lost_timeout', value=1e10),
        ]
    )
    peer = rclpy_context.create_node('predictor_test_peer')
    horizons: list[DemandHorizon] = []
    tracks: list[PointStamped] = []
    peer.create_subscription(DemandHorizon, topics.DEMAND_HORIZON, horizons.append, qos.LATCHED)
    peer.create_subscription(PointStamped, topics.OVERHEAD_TRACK, tracks.append, qos.SENSOR)
    fix_pub = peer.create_publisher(PointStamped, topics.OVERHEAD_FIX, qos.STATE)
    sent = [0]

    def step() -> bool:
        # 10 mm/s along x from (0.1, 0.1), one fix per call at 10 Hz of simulated stamps, 35
        # fixes (1-4.4 s: the demands at 10 s and 12 s stay ahead however slow the node is).
        confirmed = bool(horizons) and horizons[-1].track_state == DemandHorizon.TRACK_CONFIRMED
        if sent[0] >= 35:
            last = horizons[-1].header.stamp.sec + 1e-9 * horizons[-1].header.stamp.nanosec
            return confirmed and pred._bad_fixes >= 1 and last > 4.35
        t = 1.0 + 0.1 * sent[0]
        msg = PointStamped()
        msg.header.stamp = sec_to_time(t)
        msg.header.frame_id = 'world'
        msg.point.x, msg.point.y, msg.point.z = 0.1 + 0.01 * (t - 1.0), 0.1, 0.08
        if sent[0] > 20 and sent[0] % 10 == 5:  # broken fixes: counted, not tracked
            msg.point.x = math.nan
        fix_pub.publish(msg)
        sent[0] += 1
        return False

    try:
        assert spin_until([pred, peer], step, timeout=30.0)
        h = horizons[-1]
        assert [d.index for d in h.demands] == [0, 1]
        d0 = h.demands[0]
        # Constant velocity: at t = 10 s the top marker is at x = 0.19; the side marker is
        # 30 mm in front (-y) and below it (the default side_marker_offset).
        got = np.array([d0.pose.pose.position.x, d0.pose.pose.position.y, d0.pose.pose.position.z])
        assert got == pytest.approx([0.19, 0.07, 0.05], abs=2e-3)
        assert tracks, 'accepted fixes are republished on overhead/track'
        assert pred.session.tracker.predictor.rejections == 0  # NaN fixes never reach the filter
    finally:
        for n in (pred, peer):
            n.destroy_node()
