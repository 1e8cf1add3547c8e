"""Where a controller's axes stand now, read once without moving anything (what a hardware
run shows before it asks to move them)."""

from __future__ import annotations

from activesurv_stages.config import ControllerConfig
from activesurv_stages.drivers import make_driver


def read_positions(config: ControllerConfig, timeout: float = 1.0) -> dict[str, float]:
    """Each joint's position (m or rad) as its controller reports it now: the port opened, the
    axes found and polled once, the port closed; no motion, no homing.

    Raises:
        StageError: if the controller cannot be reached or does not answer.
    """
    driver = make_driver(config.protocol, config.port, config.baud, timeout)
    try:
        driver.connect()
        by_axis = {r.axis: r for r in driver.poll()}
    finally:
        driver.close()
    return {a.joint: a.to_si(by_axis[a.axis].position) for a in config.axes if a.axis in by_axis}
