"""A node's time to the millisecond on simulated time, for stamps the latency budget reads.

A node on simulated time sees the time of the last ``/clock`` tick (10 Hz in the graph: up to
100 ms behind, and a message that arrives before the next tick looks early).
:class:`FineClock` notes each tick as the node's clock takes it (a jump callback), with the
steady wall time, and reads simulated time between ticks off
:class:`activesurv_common.timeseries.ClockEstimate` (as the recorder stamps what it receives);
given its node, it also takes the simulated xy table's own mapping (``/sim/clock_origin``) and
then reads the time exactly, on the same host. On the wall clock it is the node's clock.
"""

from __future__ import annotations

import time

from rclpy.clock import Clock, JumpHandle, JumpThreshold, TimeJump
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from activesurv_common.ros import qos, topics
from activesurv_common.timeseries import ClockEstimate


class FineClock:
    """Simulated time between ``/clock`` ticks (the node's clock time on a wall clock)."""

    def __init__(self, clock: Clock, node: Node | None = None) -> None:
        self._clock = clock
        self._estimate = ClockEstimate()
        if node is not None:  # the simulated clock's owner's mapping, if it publishes one
            node.create_subscription(
                Float64MultiArray, topics.CLOCK_ORIGIN, self._on_origin, qos.LATCHED
            )
        threshold = JumpThreshold(
            min_forward=Duration(nanoseconds=1), min_backward=None, on_clock_change=False
        )
        self._handle: JumpHandle = clock.create_jump_callback(
            threshold, post_callback=self._on_jump
        )

    def _on_origin(self, msg: Float64MultiArray) -> None:
        if len(msg.data) >= 2:
            self._estimate.set_origin(float(msg.data[0]), float(msg.data[1]))

    def _on_jump(self, jump: TimeJump) -> None:
        self._estimate.tick(self._clock.now().nanoseconds * 1e-9, time.monotonic())

    def now(self) -> float:
        """Seconds: the node's clock, or between ticks where the ticks run."""
        coarse = self._clock.now().nanoseconds * 1e-9
        fine = self._estimate.now(time.monotonic())
        return coarse if fine is None else max(fine, coarse)
