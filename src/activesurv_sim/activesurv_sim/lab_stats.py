"""What a lab camera achieves on this machine: counts, render time, how late frames go out
(pure core; :mod:`activesurv_sim.lab_camera_node` reports it every 10 s and in /diagnostics).

A free-running lab camera exposes on its own grid (:class:`activesurv_common.pacing.
ExposureClock`) and makes each frame once the controllers have reported past its exposure, so
a busy machine delays frames but exposes them all. What a busy machine costs shows in
``delivered_ms`` (exposure to publication, median of the last 300 frames) and ``Hz``: the
exposures it got to per second (sent, dropped as configured, or without a controller's
state), against the rate asked for; the rest were lost or still wait.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, field
from typing import Any


@dataclass
class LabCameraStats:
    rate: float  # Hz asked for
    started: float  # s (monotonic) when the camera started
    exposures: int = 0
    frames: int = 0  # published
    dropped: int = 0  # rendered, then dropped as configured (frames that never arrive)
    missed: int = 0  # no controller state near the exposure: nothing to see
    lost: int = 0  # exposures older than the exposure clock's reach (a process too busy)
    render_s: float = 0.0
    delivered: deque[float] = field(default_factory=lambda: deque(maxlen=300))

    def sent(self, exposure: float, now: float) -> None:
        """A frame exposed at ``exposure`` published at ``now`` (the same clock)."""
        self.frames += 1
        self.delivered.append(now - exposure)

    def render_ms(self) -> float:
        return 1e3 * self.render_s / max(self.frames + self.dropped, 1)

    def delivered_ms(self) -> float | None:
        return 1e3 * statistics.median(self.delivered) if self.delivered else None

    def summary(self, now: float) -> str:
        """One line: the rate achieved, the counts, the render and the delivery times."""
        made = self.frames + self.dropped + self.missed  # every exposure it got to
        hz = made / max(now - self.started, 1e-9)
        slow = ' (slower than asked: the machine cannot keep up)' if hz < 0.9 * self.rate else ''
        late = self.delivered_ms()
        out = (
            f'{hz:.1f} Hz of {self.rate:g} Hz{slow}; {self.frames} frames sent, '
            f'{self.dropped} dropped, {self.missed} without state'
        )
        if self.lost:
            out += f', {self.lost} exposures lost (the process too busy to take them)'
        out += f'; render {self.render_ms():.1f} ms'
        return out + (f'; sent {late:.0f} ms after exposure (median)' if late is not None else '')

    def short(self) -> str:
        """For /diagnostics' message."""
        return f'{self.frames} frames, {self.dropped} dropped, render {self.render_ms():.1f} ms'

    def values(self) -> dict[str, Any]:
        """For /diagnostics."""
        late = self.delivered_ms()
        return dict(
            exposures=self.exposures,
            frames=self.frames,
            dropped=self.dropped,
            missed=self.missed,
            lost=self.lost,
            render_ms=round(self.render_ms(), 2),
            delivered_ms=round(late, 1) if late is not None else float('nan'),
        )
