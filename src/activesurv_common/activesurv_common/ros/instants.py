"""Steady-clock timers at instants of simulated time, on the clock owner's own mapping.

The simulated xy table publishes ``/sim/clock_origin`` (simulated = (steady - data[0]) *
data[1], on this host's steady clock). A node that acts at a simulated instant, as a triggered
camera exposes at its instant on its own clock, then needs neither ``/clock``'s next tick (10 Hz)
nor another process's message of the instant. Without the mapping (a clock from a bag, or from
another owner) :meth:`InstantTimers.at` says so and schedules nothing.

:func:`periodic` keeps a node's regular work (a stage's states, an imager's heartbeat) at its own
rate on the same mapping, on the owner's grid (``data[2]``, the phase of its ticks), so that it
does not depend on how often ``/clock`` ticks; without the mapping it runs on the node's clock.
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
        self._timers: dict[object, Timer] = {}  # instant t, or (grid, t)
        self._grids: list[tuple[float, Callable[[float], None]]] = []
        self.phase = 0.0  # the owner's grid: its ticks at phase + n / rate
        node.create_subscription(
            Float64MultiArray, topics.CLOCK_ORIGIN, self._on_origin, qos.LATCHED
        )

    def _on_origin(self, msg: Float64MultiArray) -> None:
        if len(msg.data) >= 2:
            wall0, rate = float(msg.data[0]), float(msg.data[1])
            if math.isfinite(wall0) and math.isfinite(rate) and rate > 0.0:
                started = self._origin is None
                self._origin = (wall0, rate)
                phase = float(msg.data[2]) if len(msg.data) >= 3 else 0.0
                self.phase = phase if math.isfinite(phase) else 0.0
                for period, callback in self._grids if started else ():
                    self._next(period, callback)

    @property
    def ready(self) -> bool:
        """The clock owner's mapping is known."""
        return self._origin is not None

    def now(self) -> float | None:
        """Simulated time on the mapping, or None without it."""
        if self._origin is None:
            return None
        wall0, rate = self._origin
        return (time.monotonic() - wall0) * rate

    def every(self, period: float, callback: Callable[[float], None]) -> None:
        """Call ``callback(t)`` at every simulated ``t`` = phase + n * ``period`` of the
        owner's grid, from when its mapping is known (a timer's usual lateness, no sleep)."""
        if not (math.isfinite(period) and period > 0.0):
            raise ValueError(f'period must be positive, got {period!r}')
        self._grids.append((period, callback))
        if self._origin is not None:
            self._next(period, callback)

    def _next(self, period: float, callback: Callable[[float], None]) -> None:
        """A one-shot timer to the grid's next point, then a steady periodic one."""
        now, rate = self.now(), self._origin[1] if self._origin else 1.0
        assert now is not None
        first = self.phase + (math.floor((now - self.phase) / period + 1e-6) + 1) * period
        last = [first]

        def each() -> None:
            t_now = self.now()
            assert t_now is not None
            t = self.phase + round((t_now - self.phase) / period) * period
            t = t if t > last[0] + 1e-9 else last[0] + period  # never one point twice
            last[0] = t
            callback(t)

        def start() -> None:
            self._node.create_timer(period / rate, each, clock=self._steady)
            callback(first)

        self._schedule((period, first), first, start, exact=False)

    def at(self, t: float, callback: Callable[[], None], exact: bool = True) -> bool:
        """Call ``callback`` once at simulated time ``t`` (at once if it has passed); with
        ``exact``, set ahead and then sleep to it.

        Returns:
            False, with nothing scheduled, without the mapping or if ``t`` has a timer already.
        """
        if self._origin is None or t in self._timers or not math.isfinite(t):
            return False
        self._schedule(t, t, callback, exact)
        return True

    def _schedule(self, key: object, t: float, callback: Callable[[], None], exact: bool) -> None:
        assert self._origin is not None
        wall0, rate = self._origin
        due = wall0 + t / rate
        delay = max(due - (LEAD if exact else 0.0) - time.monotonic(), 0.0)

        def fire() -> None:
            timer = self._timers.pop(key, None)
            if timer is None:
                return  # fired already (a zero-delay timer may be ready twice)
            timer.cancel()
            self._node.destroy_timer(timer)
            early = due - time.monotonic()
            if early > 0.0 and exact:
                time.sleep(early)
            callback()

        self._timers[key] = self._node.create_timer(delay, fire, clock=self._steady)


def periodic(node: Node, period: float, callback: Callable[[float], None]) -> InstantTimers:
    """``callback(t)`` every ``period`` s of simulated time, on the clock owner's mapping and
    grid once it is known; until then (a clock from a bag or another owner, or a wall clock)
    on a timer of the node's clock, at the node's time."""
    timers = InstantTimers(node)
    timers.every(period, callback)

    def fallback() -> None:
        if not timers.ready:
            callback(node.get_clock().now().nanoseconds * 1e-9)

    node.create_timer(period, fallback)
    return timers
