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
