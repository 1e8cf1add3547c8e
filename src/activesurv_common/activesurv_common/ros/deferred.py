"""Work that can wait until a demand instant's critical path has passed.

At a demand instant every camera's container images its frame at once, and on a host with
fewer cores than cameras they share the cores until the last observation is out. What a camera's
call does after its observation (the viewers' annotations, the demand's frame for the bag, the
DDS copy of the frame and its intrinsics for the recorder and viewers) then takes cores from the
cameras still imaging: 40 % of a camera's CPU at the instant (``docs/performance.md``).
:class:`Deferred` runs such work ``delay`` seconds later on the steady clock (the estimate is out
by then), in the order it was deferred; :meth:`Deferred.flush` runs what is left at once (a
node's stop: nothing is lost). A ``delay`` of 0 runs the work at once.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.timer import Timer


class Deferred:
    """A node's work run ``delay`` s (steady clock) after it was handed over."""

    def __init__(self, node: Node, delay: float) -> None:
        if not (math.isfinite(delay) and delay >= 0.0):
            raise ValueError(f'delay must be finite and >= 0, got {delay!r}')
        self._node, self.delay = node, float(delay)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._queue: deque[tuple[float, Callable[[], None]]] = deque()
        self._timer: Timer | None = None
        self.ran = 0  # work done, on time or flushed
        self.failed = 0  # work that raised when flushed

    def __len__(self) -> int:
        return len(self._queue)

    def __call__(self, work: Callable[[], None]) -> None:
        """Run ``work`` ``delay`` s from now (at once if the delay is 0)."""
        if self.delay <= 0.0:
            self._run(work)
            return
        self._queue.append((time.monotonic() + self.delay, work))
        if self._timer is None:
            self._arm(self.delay)

    def flush(self) -> int:
        """Run all the work waiting, now, in order (a node's stop); returns how much work ran.
        Work that raises (its publisher's context already shut down) is logged and the rest
        still runs."""
        ran = 0
        try:
            self._disarm()
        except Exception:  # the node's context already gone: its timer goes with it
            self._timer = None
        while self._queue:
            ran += 1
            try:
                self._run(self._queue.popleft()[1])
            except Exception as exc:  # any work's error: the rest must still go out
                self.failed += 1
                why = f'deferred work failed at stop: {type(exc).__name__}: {exc}'
                self._node.get_logger().warning(why)
        return ran

    def _arm(self, wait: float) -> None:
        self._timer = self._node.create_timer(max(wait, 0.0), self._on_timer, clock=self._steady)

    def _disarm(self) -> None:
        timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
            self._node.destroy_timer(timer)

    def _on_timer(self) -> None:
        if self._timer is None:
            return  # flushed already (a zero-delay timer may be ready twice)
        self._disarm()
        now = time.monotonic()
        while self._queue and self._queue[0][0] <= now + 1e-4:
            self._run(self._queue.popleft()[1])
        if self._queue:
            self._arm(self._queue[0][0] - time.monotonic())

    def _run(self, work: Callable[[], None]) -> None:
        self.ran += 1
        work()
