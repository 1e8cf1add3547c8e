"""The simulated xy table's demand instants: a state (and a tick) of its own at each one.

On a capture request the table publishes ``sim/planned_object_state`` (what its program reaches
at the instant: the simulated cameras render ahead with it) and sets a timer for the instant.
It publishes the object's state stamped exactly then: the truth the bag, the evaluation and
the simulated cameras' check of what they rendered ahead hold against. With
``instant_state_delay`` > 0 and no tick at the instant, the timer is set that delay (simulated
seconds) past the instant, so the state goes out after the cameras' imaging: no node of the
system reads it, and on two cores its publication and its six readers took 1.5-2.5 ms of CPU
from the three cameras imaging the instant, and the table's own wake-up at the instant 0.2 ms
more (docs/performance.md). Its stamp is the instant's all the same; a state of a later time,
and a stop, send it at once, so states keep their order.

With :meth:`TableInstants.relay_to` it also sends the states around each requested instant on
``sim/instant_object_state``, for the simulated cameras that image only on requests
(:mod:`activesurv_sim.instant_window`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.timer import Timer

from activesurv_common.ros.conversions import time_to_sec
from activesurv_interfaces.msg import CaptureRequest
from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_sim.instant_window import InstantWindows


class TableInstants:
    """A table node's demand instants (see the module).

    Args:
        node: the table node (its timers).
        sim_time: the node's simulated time now.
        wall0: the steady time simulated 0 began at, None before it (own clock); None as a
            whole when the node runs on someone else's /clock.
        rtf: simulated seconds per wall second.
        states: the object's state messages at a simulated time.
        planned: the ``sim/planned_object_state`` publisher.
        publish_at: publishes the states (and a tick) at a time: ``(t, states, tick)``.
        tick: a /clock tick at each instant too (then the state goes with it, undeferred).
        delay: simulated seconds the instant's state waits (0: none).
    """

    def __init__(
        self,
        node: Node,
        sim_time: Callable[[], float],
        wall0: Callable[[], float | None] | None,
        rtf: float,
        states: Callable[[float], list[ObjectStateMsg]],
        planned: Publisher,
        publish_at: Callable[[float, bool, bool], None],
        tick: bool,
        delay: float,
    ) -> None:
        if not (math.isfinite(delay) and delay >= 0.0):
            raise ValueError(f'instant_state_delay must be finite and >= 0, got {delay!r}')
        self._node, self._sim_time, self._wall0, self._rtf = node, sim_time, wall0, rtf
        self._states, self._planned, self._publish_at = states, planned, publish_at
        self._tick = tick
        self._delay = 0.0 if tick else delay
        self.fired: dict[float, Timer | None] = {}  # instants scheduled (timer) or past (None)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._relay: tuple[Publisher, InstantWindows[ObjectStateMsg]] | None = None

    def relay_to(self, publisher: Publisher, before: float, after: float) -> None:
        """Send the states stamped within ``[t - before, t + after]`` of each requested
        instant ``t`` on ``publisher`` too, as :meth:`published` is told of them."""
        self._relay = (publisher, InstantWindows(before, after))

    def published(self, t: float, states: list[ObjectStateMsg]) -> None:
        """The table published ``states`` stamped ``t``: relayed if near a requested instant."""
        if self._relay is not None and states:
            pub, windows = self._relay
            for state in windows.published(t, states):
                pub.publish(state)

    def on_request(self, msg: CaptureRequest) -> None:
        t = time_to_sec(msg.demand_instant)
        if self._relay is not None:  # its window's states gone out already, again (any time)
            pub, windows = self._relay
            for state in windows.requested(t):
                pub.publish(state)
        if t in self.fired or not t > self._sim_time():
            return  # already scheduled (or a request replayed after its instant)
        for state in self._states(t):
            self._planned.publish(state)
        # One timer, at the instant plus the delay: the table's process does not wake at the
        # instant itself, where the cameras image.
        if self._wall0 is None:
            # On someone else's clock: a simulated-time timer fires at its first tick >= t.
            delay = t + self._delay - self._sim_time()
            self.fired[t] = self._node.create_timer(delay, lambda: self._fire(t))
            return
        wall0 = self._wall0()
        if wall0 is None:
            return
        delay = max((t + self._delay) / self._rtf - (time.monotonic() - wall0), 0.0)
        self.fired[t] = self._node.create_timer(delay, lambda: self._fire(t), clock=self._steady)

    def waiting(self, before: float | None = None) -> list[float]:
        """The instants passed (before ``before``, if given) whose state still waits its
        delay, oldest first."""
        end = self._sim_time() if before is None else before
        return sorted(k for k, v in self.fired.items() if v is not None and k <= end)

    def flush(self) -> None:
        """Send the states of the instants passed and still waiting, now, oldest first (a
        later state goes out, or a stop)."""
        for t in self.waiting():
            self._fire(t)

    def _fire(self, t: float) -> None:
        timer = self.fired.get(t)
        if timer is None:
            return  # sent already (flushed, or a zero-delay timer ready twice)
        timer.cancel()
        self._node.destroy_timer(timer)
        self.fired[t] = None
        for earlier in self.waiting(before=t):  # an earlier instant still waiting goes first
            self._fire(earlier)
        self._publish_at(t, True, self._tick)
        # Keep the fired instants a while (a request may come again), not for hours.
        self.fired = {k: v for k, v in self.fired.items() if k > t - 60.0}
