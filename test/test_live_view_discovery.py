"""The live view's topic discovery backs off while the graph holds nothing new to serve, and a
wanted topic that appears later is still served, within the longest period."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import Any

import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


@pytest.mark.node
def test_live_view_discovery_backs_off_and_still_serves_a_late_topic(
    spin_until: Callable[..., bool],
) -> None:
    from rclpy.parameter import Parameter
    from std_msgs.msg import String

    from activesurv_liveview.live_view_node import LiveViewNode

    topic = f'/late_{time.monotonic_ns()}/target_estimate'
    params = [
        Parameter('port', value=_free_port()),
        Parameter('topics', value=['/late_*/target_estimate']),  # nothing else of this host
        Parameter('discovery_period', value=0.05),
        Parameter('discovery_period_max', value=0.4),
    ]
    view = LiveViewNode(parameter_overrides=params)
    other: Any = None
    try:
        # Nothing new to serve: the period doubles up to the longest.
        assert spin_until([view], lambda: view._backoff.period == pytest.approx(0.4), timeout=5.0)
        assert view._discovery.timer_period_ns == 400_000_000
        other = view.create_publisher(String, topic, 10)  # appears now
        started = time.monotonic()
        assert spin_until([view], lambda: view.channels.get(topic) is not None, timeout=5.0)
        assert time.monotonic() - started < 0.4 + 0.5  # within the longest period (+ slack)
        assert view._backoff.period == pytest.approx(0.05)  # found one: back to the period
    finally:
        if other is not None:
            view.destroy_publisher(other)
        view.destroy_node()
