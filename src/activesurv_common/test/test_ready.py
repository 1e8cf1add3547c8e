"""``announce_when_matched``: a node says it is ready only once its topics are matched."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from activesurv_common.ros import qos, topics
from activesurv_common.ros.ready import announce_when_matched

pytestmark = pytest.mark.node  # in-process rclpy nodes


def test_a_node_is_ready_only_once_its_reader_and_its_writer_are_matched(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from std_msgs.msg import String

    reader = rclpy_context.create_node('ready_reader')
    writer = rclpy_context.create_node('ready_writer')
    listener = rclpy_context.create_node('ready_listener')
    nodes = [reader, writer, listener]
    try:
        heard: list[str] = []
        listener.create_subscription(String, topics.READY, lambda m: heard.append(m.data), 10)
        reader.create_subscription(String, 'ready_test/fix', lambda _: None, qos.STATE)
        announce_when_matched(reader, inputs=['ready_test/fix'])
        fix = writer.create_publisher(String, 'ready_test/fix', qos.STATE)
        announce_when_matched(writer, outputs={'ready_test/fix': 2})
        # The reader has its publisher: it says so. The writer has one reader of two: not yet.
        assert spin_until(nodes, lambda: '/ready_reader' in heard, timeout=10.0), heard
        spin_until(nodes, lambda: False, timeout=0.5)
        assert '/ready_writer' not in heard, heard
        assert fix.get_subscription_count() == 1
        listener.create_subscription(String, 'ready_test/fix', lambda _: None, qos.STATE)
        assert spin_until(nodes, lambda: '/ready_writer' in heard, timeout=10.0), heard
        spin_until(nodes, lambda: False, timeout=0.3)
        assert sorted(heard) == ['/ready_reader', '/ready_writer'], 'each says it once'
    finally:
        for n in nodes:
            n.destroy_node()


def test_a_reader_without_a_publisher_is_not_ready(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from std_msgs.msg import String

    reader = rclpy_context.create_node('lonely_reader')
    listener = rclpy_context.create_node('lonely_listener')
    try:
        heard: list[str] = []
        listener.create_subscription(String, topics.READY, lambda m: heard.append(m.data), 10)
        reader.create_subscription(String, 'ready_test/nobody', lambda _: None, qos.STATE)
        announce_when_matched(reader, inputs=['ready_test/nobody'])
        spin_until([reader, listener], lambda: False, timeout=0.6)
        assert heard == []
    finally:
        reader.destroy_node()
        listener.destroy_node()
