"""The imager's software trigger calls the driver's Trigger service ahead of each instant."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest

from activesurv_imaging.ros.software_trigger import SoftwareTrigger

pytestmark = pytest.mark.node


def test_the_service_is_called_lead_seconds_before_the_instant(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from std_srvs.srv import Trigger

    driver = rclpy_context.create_node('fake_driver')
    imager = rclpy_context.create_node('fake_imager')
    calls: list[float] = []

    def on_call(request: Any, response: Any) -> Any:
        calls.append(time.time())
        response.success = True
        return response

    driver.create_service(Trigger, '/cam9_camera/trigger', on_call)
    trigger = SoftwareTrigger(imager, '/cam9_camera/trigger', lead=0.05)
    try:
        assert spin_until([driver, imager], trigger.client.service_is_ready, timeout=5.0)
        instant = time.time() + 0.5
        trigger.arm(7, instant)
        trigger.arm(7, instant)  # once per demand
        assert spin_until([driver, imager], lambda: len(calls) >= 1, timeout=5.0)
        spin_until([driver, imager], lambda: False, timeout=0.3)
        assert len(calls) == 1
        assert calls[0] == pytest.approx(instant - 0.05, abs=0.03)
        trigger.arm(8, time.time() - 1.0)  # already past: called at once, counted late
        assert spin_until([driver, imager], lambda: len(calls) >= 2, timeout=5.0)
        assert trigger.late == 1
    finally:
        driver.destroy_node()
        imager.destroy_node()
