"""A hardware run's stage faults, from the stage bridges' recorded diagnostics.

Each bridge names its diagnostics ``activesurv/stage_bridge/<stage>`` and reports ERROR while its
controller is lost, an axis faulted (a stall) or the e-stop is raised; the message says which.
"""

from __future__ import annotations

from typing import Any

BRIDGE_STATUS = 'activesurv/stage_bridge/'
ERROR = 2  # diagnostic_msgs/DiagnosticStatus.ERROR


class StageFaults:
    """A hardware run's stage faults from the bridges' recorded diagnostics: per stage, when
    a fault began (``why``: the bridge's message) and when it cleared (``why`` '')."""

    def __init__(self) -> None:
        self.events: list[dict[str, Any]] = []
        self._now: dict[str, str] = {}

    def hear(self, t: float, msg: Any) -> None:
        for status in msg.status:
            if not str(status.name).startswith(BRIDGE_STATUS):
                continue
            level = status.level
            level = level[0] if isinstance(level, (bytes, bytearray)) else int(level)
            why = str(status.message) if level >= ERROR else ''
            stage = str(status.name)[len(BRIDGE_STATUS) :]
            if why != self._now.get(stage, ''):
                if why and self._now.get(stage):
                    continue  # still faulted (the message changes with the counters)
                self._now[stage] = why
                if t >= 0.0:  # during the run (a bridge reports 'disconnected' until it connects)
                    self.events.append({'stage': stage, 't': round(float(t), 3), 'why': why})
