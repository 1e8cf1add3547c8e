"""In-process node test: capture request + observations in, TargetEstimate out (over DDS)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_fusion.fusion_node import FusionNode

pytestmark = pytest.mark.node  # in-process rclpy nodes


@pytest.fixture
def fusion_node(rclpy_context: Any) -> Iterator[FusionNode]:
    node = FusionNode(parameter_overrides=[Parameter('collect_timeout', value=0.5)])
    yield node
    node.destroy_node()


def _observation(cam: str, index: int, x: float, status: int = 0) -> Any:
    from activesurv_interfaces.msg import MarkerObservation

    m = MarkerObservation(camera_id=cam, demand_index=index, status=status)
    m.header.frame_id = 'world'
    m.position.x, m.position.y, m.position.z = x, 0.1, 0.04
    m.normal.y = -1.0
    m.covariance = np.diag([1e-7] * 3 + [1e-5] * 3).reshape(-1).tolist()
    if status != 0:
        m.reason = 'marker not found'
    return m


def test_request_and_observations_give_an_estimate(
    fusion_node: FusionNode, spin_until: Callable[..., bool], rclpy_context: Any
) -> None:
    from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, TargetEstimate

    peer = rclpy_context.create_node('fusion_test_peer')
    got: list[TargetEstimate] = []
    try:
        req_pub = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS_LATCHED)
        obs_pub = peer.create_publisher(
            MarkerObservation, topics.MARKER_OBSERVATIONS, qos.EVENTS_LATCHED
        )
        peer.create_subscription(TargetEstimate, topics.TARGET_ESTIMATE, got.append, qos.RESULTS)
        assert spin_until(
            [fusion_node, peer],
            lambda: req_pub.get_subscription_count() > 0 and obs_pub.get_subscription_count() > 0,
        )
        stamp = fusion_node.get_clock().now().to_msg()
        req = CaptureRequest(demand_index=5, camera_ids=['cam1', 'cam2', 'cam3', 'cam4'])
        req.demand_instant = stamp
        req_pub.publish(req)
        for cam, x in (('cam1', 0.2), ('cam2', 0.2003), ('cam3', 0.25), ('cam4', 0.1998)):
            m = _observation(cam, 5, x)
            m.header.stamp = stamp
            obs_pub.publish(m)
        assert spin_until([fusion_node, peer], lambda: len(got) == 1)
        est = got[0]
        assert est.demand_index == 5
        assert est.status == TargetEstimate.STATUS_OK
        assert list(est.cameras_faulty) == ['cam3']
        assert sorted(est.cameras_used) == ['cam1', 'cam2', 'cam4']
        assert est.position.x == pytest.approx(0.2, abs=5e-4)
        assert est.region_lower[0] <= est.position.x <= est.region_upper[0]

        # A demand where one camera fails and the others never answer still gets an answer.
        req2 = CaptureRequest(demand_index=6, camera_ids=['cam1', 'cam2'])
        req2.demand_instant = fusion_node.get_clock().now().to_msg()
        req_pub.publish(req2)
        obs_pub.publish(_observation('cam1', 6, 0.2, status=MarkerObservation.STATUS_NOT_FOUND))
        assert spin_until([fusion_node, peer], lambda: len(got) == 2, timeout=10.0)
        assert got[1].status == TargetEstimate.STATUS_NO_OBSERVATIONS
        assert 'marker not found' in got[1].reason
        assert list(got[1].cameras_missing) == ['cam2']
    finally:
        peer.destroy_node()


def test_invalid_parameters_are_rejected_with_a_reason(fusion_node: FusionNode) -> None:
    results = fusion_node.set_parameters([Parameter('z_sigma', value=-1.0)])
    assert not results[0].successful
    results = fusion_node.set_parameters([Parameter('collect_timeout', value=float('nan'))])
    assert not results[0].successful
    assert 'collect_timeout' in results[0].reason or 'range' in results[0].reason.lower()
    assert fusion_node.set_parameters([Parameter('collect_timeout', value=1.5)])[0].successful


def test_a_demand_a_camera_never_answers_is_decided_at_its_deadline_without_clock_ticks(
    spin_until: Callable[..., bool], rclpy_context: Any
) -> None:
    """On simulated time, the deadline is kept on the clock owner's mapping: the demand is
    answered at its deadline though ``/clock`` does not tick (a graph's table ticks it every
    0.4 s only), not at the next tick."""
    import time

    from std_msgs.msg import Float64MultiArray

    from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, TargetEstimate

    timeout = 0.3
    node = FusionNode(
        parameter_overrides=[
            Parameter('collect_timeout', value=timeout),
            Parameter('use_sim_time', value=True),
        ]
    )
    peer = rclpy_context.create_node('fusion_deadline_peer')
    got: list[tuple[float, TargetEstimate]] = []
    try:
        origin = peer.create_publisher(Float64MultiArray, topics.CLOCK_ORIGIN, qos.LATCHED)
        wall0 = time.monotonic() - 10.0  # simulated time 10 s now, on this host's clock
        origin.publish(Float64MultiArray(data=[wall0, 1.0, 0.0]))
        req_pub = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS_LATCHED)
        obs_pub = peer.create_publisher(
            MarkerObservation, topics.MARKER_OBSERVATIONS, qos.EVENTS_LATCHED
        )
        peer.create_subscription(
            TargetEstimate, topics.TARGET_ESTIMATE, lambda m: got.append((time.monotonic(), m)), 10
        )
        assert spin_until(
            [node, peer],
            lambda: (
                req_pub.get_subscription_count() > 0
                and obs_pub.get_subscription_count() > 0
                and node._deadlines.ready
            ),
        )
        instant = time.monotonic() - wall0 + 0.2  # simulated
        req = CaptureRequest(demand_index=3, camera_ids=['cam1', 'cam2'])
        req.demand_instant.sec, req.demand_instant.nanosec = int(instant), int(instant % 1 * 1e9)
        req_pub.publish(req)
        obs = _observation('cam1', 3, 0.2)
        obs.header.stamp = req.demand_instant
        obs_pub.publish(obs)
        assert spin_until([node, peer], lambda: bool(got), timeout=5.0)
        when, est = got[0]
        assert est.demand_index == 3
        assert list(est.cameras_missing) == ['cam2']
        late = (when - wall0) - (instant + timeout)  # after the deadline, simulated = wall here
        assert -0.01 < late < 0.15, late
    finally:
        peer.destroy_node()
        node.destroy_node()
