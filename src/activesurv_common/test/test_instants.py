"""``InstantTimers``: a callback at a simulated instant, on the clock owner's mapping."""

from __future__ import annotations

import itertools
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


def test_periodic_work_keeps_its_rate_on_the_owners_grid_without_clock_ticks(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """A stage's states or an imager's heartbeat: at its own rate, on the grid the clock owner
    publishes (phase), with no /clock tick at all; on the node's clock before the mapping."""
    from std_msgs.msg import Float64MultiArray

    from activesurv_common.ros.instants import periodic

    node = rclpy_context.create_node('periodic_test')
    peer = rclpy_context.create_node('periodic_test_peer')
    try:
        fired: list[tuple[float, float]] = []
        timers = periodic(node, 0.1, lambda t: fired.append((t, time.monotonic())))
        assert spin_until([node, peer], lambda: len(fired) >= 2, timeout=5.0)
        assert not timers.ready  # before the mapping: the node's own (system) clock
        assert abs(fired[-1][0] - time.time()) < 1.0
        origin = peer.create_publisher(Float64MultiArray, topics.CLOCK_ORIGIN, qos.LATCHED)
        wall0, rate, phase = time.monotonic() - 3.0, 2.0, 0.05
        origin.publish(Float64MultiArray(data=[wall0, rate, phase]))
        assert spin_until([node, peer], lambda: timers.ready, timeout=10.0)
        fired.clear()
        spin_until([node, peer], lambda: False, timeout=0.6)
        ts = [t for t, _ in fired]
        assert 9 <= len(ts) <= 13, ts  # 0.6 s of wall time is 1.2 s of simulated time
        steps = [b - a for a, b in itertools.pairwise(ts)]
        assert all(abs(s - 0.1) < 1e-6 for s in steps), ts  # every point once, none skipped
        assert all(abs((t - phase) / 0.1 - round((t - phase) / 0.1)) < 1e-6 for t in ts), ts
        for t, wall in fired:  # at its point, a timer's lateness after it
            due = wall0 + t / rate
            assert due - 0.002 <= wall < due + 0.05, wall - due
    finally:
        node.destroy_node()
        peer.destroy_node()
