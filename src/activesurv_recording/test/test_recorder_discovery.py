"""The recorder's topic discovery backs off while the graph holds nothing new, and a topic that
appears later is still found, within the longest period."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest


@pytest.mark.node
def test_discovery_backs_off_and_still_finds_a_late_topic(
    tmp_path: Path, spin_until: Callable[..., bool]
) -> None:
    from rclpy.parameter import Parameter
    from std_msgs.msg import String

    from activesurv_recording.recorder_node import RecorderNode

    params = [
        Parameter('output', value=str(tmp_path / 'bag')),
        Parameter('discovery_period', value=0.05),
        Parameter('discovery_period_max', value=0.4),
    ]
    rec = RecorderNode(parameter_overrides=params)
    other: Any = None
    try:
        # Nothing new in a quiet graph: the period doubles up to the longest.
        assert spin_until([rec], lambda: rec._backoff.period == pytest.approx(0.4), timeout=5.0)
        assert rec._discovery.timer_period_ns == 400_000_000
        topic = f'/late_{time.monotonic_ns()}'
        other = rec.create_publisher(String, topic, 10)  # appears now
        started = time.monotonic()
        assert spin_until([rec], lambda: topic in rec.subscribed, timeout=5.0)
        assert time.monotonic() - started < 0.4 + 0.5  # within the longest period (+ slack)
        assert rec._backoff.period == pytest.approx(0.05)  # found one: back to the period
    finally:
        if other is not None:
            rec.destroy_publisher(other)
        rec.close()
        rec.destroy_node()


@pytest.mark.node
def test_on_simulated_time_discovery_does_not_back_off_before_the_first_tick(
    tmp_path: Path, spin_until: Callable[..., bool]
) -> None:
    """The graph is still coming up while simulated time waits: a topic that appears then is
    found within the period (the orchestrator holds time until every topic is recorded)."""
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock

    from activesurv_recording.recorder_node import RecorderNode

    params = [
        Parameter('output', value=str(tmp_path / 'bag')),
        Parameter('use_sim_time', value=True),
        Parameter('discovery_period', value=0.05),
        Parameter('discovery_period_max', value=0.4),
    ]
    rec = RecorderNode(parameter_overrides=params)
    pub: Any = None
    try:
        ends = time.monotonic() + 0.6  # time enough for 0.05 -> 0.4 s
        spin_until([rec], lambda: time.monotonic() > ends, timeout=2.0)
        assert rec._backoff.period == pytest.approx(0.05)
        pub = rec.create_publisher(Clock, '/clock', 10)  # simulated time starts
        assert spin_until([rec], lambda: '/clock' in rec.subscribed, timeout=5.0)
        assert spin_until([rec], lambda: (pub.publish(Clock()), rec.clock_heard)[1], timeout=5.0)
        assert spin_until([rec], lambda: rec._backoff.period == pytest.approx(0.4), timeout=5.0)
    finally:
        if pub is not None:
            rec.destroy_publisher(pub)
        rec.close()
        rec.destroy_node()
