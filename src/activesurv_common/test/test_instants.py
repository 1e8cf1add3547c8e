"""``InstantTimers``: a callback at a simulated instant, on the clock owner's mapping."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest

from activesurv_common.ros import qos, topics
from activesurv_common.ros.instants import InstantTimers

pytestmark = pytest.mark.node  # in-process rclpy nodes


def test_a_callback_comes_at_its_simulated_instant_not_before(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from std_msgs.msg import Float64MultiArray

    node = rclpy_context.create_node('instants_test')
    peer = rclpy_context.create_node('instants_test_peer')
    try:
        timers = InstantTimers(node)
        assert not timers.at(1.0, lambda: None), 'scheduled without the mapping'
        origin = peer.create_publisher(Float64MultiArray, topics.CLOCK_ORIGIN, qos.LATCHED)
        wall0, rate = time.monotonic() - 10.0, 2.0  # simulated 20 s now, twice the wall's pace
        origin.publish(Float64MultiArray(data=[wall0, rate]))
        assert spin_until([node, peer], lambda: timers.ready, timeout=10.0)
        fired: list[tuple[str, float]] = []
        t = (time.monotonic() - wall0) * rate + 0.4  # 0.2 s of wall time from now
        assert timers.at(t, lambda: fired.append(('a', time.monotonic())))
        assert not timers.at(t, lambda: fired.append(('twice', time.monotonic())))
        assert timers.at(0.5, lambda: fired.append(('past', time.monotonic())))
        assert spin_until([node, peer], lambda: len(fired) >= 2, timeout=5.0)
        spin_until([node, peer], lambda: False, timeout=0.2)
        assert [name for name, _ in fired] == ['past', 'a']
        due = wall0 + t / rate
        assert due <= fired[1][1] < due + 0.1, fired[1][1] - due
    finally:
        node.destroy_node()
        peer.destroy_node()
