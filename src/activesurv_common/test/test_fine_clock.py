"""``FineClock``: simulated time between /clock ticks, for the latency budget's frame step."""

from __future__ import annotations

import time

from rclpy.clock import ROSClock
from rclpy.time import Time

from activesurv_common.ros.fine_clock import FineClock


def _tick(clock: ROSClock, t: float) -> None:
    clock.set_ros_time_override(Time(nanoseconds=round(t * 1e9)))


def test_between_ticks_the_time_runs_on_at_the_ticks_rate() -> None:
    clock = ROSClock()
    clock._set_ros_time_is_active(True)
    fine = FineClock(clock)
    for i in range(5):  # ticks 20 ms apart at 1x real time
        _tick(clock, 1.0 + 0.02 * i)
        time.sleep(0.02)
    coarse = clock.now().nanoseconds * 1e-9
    assert abs(coarse - 1.08) < 1e-9  # the node's clock: the last tick
    later = fine.now()
    assert later > coarse + 0.01  # ~20 ms past the last tick by now
    assert later < coarse + 0.25  # never far beyond it (a paused clock stays paused)
    assert fine.now() >= later  # never backwards


def test_on_the_wall_clock_it_is_the_clock() -> None:
    clock = ROSClock()  # ROS time inactive: the system clock, no ticks
    fine = FineClock(clock)
    assert abs(fine.now() - time.time()) < 0.05
