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
