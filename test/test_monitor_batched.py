"""A run's monitor handles the graph's messages in batches while the graph runs
(``Observer.spin_batched``): it is not woken at every observation of a demand instant, and
loses none of what came while it slept."""

from __future__ import annotations

import time
from typing import Any

import pytest

pytestmark = pytest.mark.node


def test_what_comes_while_the_monitor_sleeps_is_handled_in_one_batch(rclpy_context: Any) -> None:
    from activesurv_bringup.experiments.graph import RunMonitor
    from activesurv_common.ros import qos, topics
    from activesurv_interfaces.msg import TargetEstimate

    talker = rclpy_context.create_node('fusion_stand_in')
    pub = talker.create_publisher(TargetEstimate, topics.TARGET_ESTIMATE, qos.EVENTS_LATCHED)
    with RunMonitor([]) as monitor:
        deadline = time.monotonic() + 10.0
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            monitor.spin(0.05)
        assert pub.get_subscription_count() >= 1
        for i in range(20):
            pub.publish(TargetEstimate(demand_index=i))
        assert monitor.estimates == {}  # nothing is handled before the monitor spins
        for _ in range(4):  # delivery over DDS takes its time on a loaded host
            monitor.spin_batched(0.1)
            if len(monitor.estimates) == 20:
                break
        assert sorted(monitor.estimates) == list(range(20))
    talker.destroy_node()


def test_the_monitor_counts_the_observations_from_requests_and_estimates(
    rclpy_context: Any,
) -> None:
    """It does not read the observations (a reader more of each at the demand instants): those
    the recorder must hold before the run stops are the cameras each request asked less those
    its estimate names missing."""
    from activesurv_bringup.experiments.graph import RunMonitor
    from activesurv_common.ros import qos, topics
    from activesurv_interfaces.msg import CaptureRequest, TargetEstimate

    talker = rclpy_context.create_node('dispatch_and_fusion_stand_in')
    requests = talker.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS_LATCHED)
    estimates = talker.create_publisher(TargetEstimate, topics.TARGET_ESTIMATE, qos.EVENTS_LATCHED)
    with RunMonitor([]) as monitor:
        deadline = time.monotonic() + 10.0
        while (
            time.monotonic() < deadline
            and min(requests.get_subscription_count(), estimates.get_subscription_count()) < 1
        ):
            monitor.spin(0.05)
        requests.publish(CaptureRequest(demand_index=3, camera_ids=['cam1', 'cam2', 'cam3']))
        estimates.publish(TargetEstimate(demand_index=3, cameras_missing=['cam2']))
        requests.publish(CaptureRequest(demand_index=4, camera_ids=['cam1']))  # not decided
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and not (3 in monitor.estimates and 4 in monitor._asked):
            monitor.spin(0.05)
        assert monitor.observations_expected() == {(3, 'cam1'), (3, 'cam3')}
        observations = monitor.node.resolve_topic_name(topics.MARKER_OBSERVATIONS)
        recorded = {observations: 1, monitor.node.resolve_topic_name(topics.CAPTURE_REQUEST): 2}
        monitor.recorded = {**recorded, monitor.node.resolve_topic_name(topics.TARGET_ESTIMATE): 1}
        assert monitor.unrecorded() == {observations: 1}
        assert observations not in {s.topic_name for s in monitor.node.subscriptions}
    talker.destroy_node()
