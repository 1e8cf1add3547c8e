"""Steady-clock timers at instants of simulated time, on the clock owner's own mapping.

The simulated xy table publishes ``/sim/clock_origin`` (simulated = (steady - data[0]) *
data[1], on this host's steady clock). A node that acts at a simulated instant, as a triggered
camera exposes at its instant on its own clock, then needs neither ``/clock``'s next tick (10 Hz)
nor another process's message of the instant. Without the mapping (a clock from a bag, or from
another owner) :meth:`InstantTimers.at` says so and schedules nothing.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.timer import Timer
from std_msgs.msg import Float64MultiArray

from activesurv_common.ros import qos, topics

LEAD = 0.002
"""s a timer is set ahead of its instant, then sleeps to it: a timer's callback comes about
1 ms late here (the executor's timer thread wakes, then this one), a sleep's wake-up 0.1 ms."""


class InstantTimers:
    """One-shot timers at simulated instants, each on the steady clock."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._origin: tuple[float, float] | None = None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timers: dict[float, Timer] = {}
        node.create_subscription(
            Float64MultiArray, topics.CLOCK_ORIGIN, self._on_origin, qos.LATCHED
        )

    def _on_origin(self, msg: Float64MultiArray) -> None:
        if len(msg.data) >= 2:
            wall0, rate = float(msg.data[0]), float(msg.data[1])
            if math.isfinite(wall0) and math.isfinite(rate) and rate > 0.0:
                self._origin = (wall0, rate)

    @property
    def ready(self) -> bool:
        """The clock owner's mapping is known."""
        return self._origin is not None

    def at(self, t: float, callback: Callable[[], None]) -> bool:
        """Call ``callback`` once at simulated time ``t`` (at once if it has passed).

        Returns:
            False, with nothing scheduled, without the mapping or if ``t`` has a timer already.
        """
        if self._origin is None or t in self._timers or not math.isfinite(t):
            return False
        wall0, rate = self._origin
        due = wall0 + t / rate
        delay = max(due - LEAD - time.monotonic(), 0.0)

        def fire() -> None:
            timer = self._timers.pop(t, None)
            if timer is None:
                return  # fired already (a zero-delay timer may be ready twice)
            timer.cancel()
            self._node.destroy_timer(timer)
            early = due - time.monotonic()
            if early > 0.0:
                time.sleep(early)
            callback()

        self._timers[t] = self._node.create_timer(delay, fire, clock=self._steady)
        return True
