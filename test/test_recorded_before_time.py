"""Simulated time waits for the recorder to record every published topic
(``graph._wait_until_recorded``): the recorder finds topics by polling the graph, and a camera
whose container came up last had its first frames unrecorded (its replay then missed them)."""

from __future__ import annotations

import time
from typing import Any

import pytest

pytestmark = pytest.mark.node


def test_a_published_topic_is_unrecorded_until_the_recorder_subscribes(rclpy_context: Any) -> None:
    from rclpy.qos import QoSProfile
    from std_msgs.msg import String

    from activesurv_bringup.experiments.graph import RunMonitor

    topic = f'/frames_{time.monotonic_ns()}'
    quiet = f'/quiet_{time.monotonic_ns()}'
    talker = rclpy_context.create_node('talker')
    recorder = rclpy_context.create_node('recorder')
    talker.create_publisher(String, topic, QoSProfile(depth=1))
    talker.create_publisher(String, quiet, QoSProfile(depth=1))
    with RunMonitor([]) as monitor:

        def unrecorded() -> set[str]:
            return monitor.unrecorded_topics({quiet}) & {topic, quiet}

        deadline = time.monotonic() + 10.0
        while unrecorded() != {topic} and time.monotonic() < deadline:
            monitor.spin(0.05)
        assert unrecorded() == {topic}  # published, not recorded; an excluded one not asked
        recorder.create_subscription(String, topic, lambda _: None, QoSProfile(depth=1))
        deadline = time.monotonic() + 10.0
        while unrecorded() and time.monotonic() < deadline:
            monitor.spin(0.05)
        assert unrecorded() == set()
        assert topic in monitor._recording  # not asked again
    talker.destroy_node()
    recorder.destroy_node()
