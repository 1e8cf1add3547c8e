"""A software-triggered camera driver's ``std_srvs/Trigger`` service, called ahead of each
demand instant.

``trigger: software`` in the hardware file, for a ROS 2 driver's topic: the driver exposes when
its trigger service is called. The imager calls it ``trigger_lead`` seconds before the demand
instant (the service call's own latency: about a millisecond on one host), so that the
exposure falls on the instant; the frame is then taken as a triggered one (within
``frame_tolerance`` of the instant).
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node
from std_srvs.srv import Trigger


class SoftwareTrigger:
    """Calls ``service`` at each armed instant minus ``lead`` (on the node's clock)."""

    def __init__(self, node: Node, service: str, lead: float) -> None:
        self.node, self.lead = node, float(lead)
        self.client = node.create_client(Trigger, service)
        self.service = service
        self.timers: dict[int, Any] = {}
        self.calls = self.refused = self.late = 0

    def _now(self) -> float:
        return float(self.node.get_clock().now().nanoseconds) * 1e-9

    def arm(self, index: int, instant: float) -> None:
        """Trigger the camera for demand ``index`` at ``instant`` (s); once per demand."""
        if index in self.timers:
            return
        wait = instant - self.lead - self._now()
        if wait <= 0.0:
            self.late += 1
            self.timers[index] = None
            self._call(index)
            return
        self.timers[index] = self.node.create_timer(wait, lambda: self._fire(index))

    def _fire(self, index: int) -> None:
        timer = self.timers.get(index)
        if timer is not None:
            timer.cancel()
            self.node.destroy_timer(timer)
            self.timers[index] = None
        self._call(index)

    def _call(self, index: int) -> None:
        if not self.client.service_is_ready():
            self.refused += 1
            self.node.get_logger().warning(  # type: ignore[no-untyped-call]
                f'demand {index}: trigger service {self.service} not available',
                throttle_duration_sec=5.0,
            )
            return
        self.calls += 1
        self.client.call_async(Trigger.Request())
        if len(self.timers) > 100:  # forget old demands
            for k in sorted(self.timers)[:50]:
                self.timers.pop(k, None)
