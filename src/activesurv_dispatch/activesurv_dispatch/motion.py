"""Motion control and capture timing (paper Section III-C-4), pure core.

Desired poses become time-parameterised stage goals: the positions, the motion class's velocity
caps (the stages arrive as early as they can and wait, so the camera is still at the demand
instant), and the demand instant as the arrival time. A goal is sent only when it changes by more
than a deadband, so a stable plan does not flood the stage controllers.

Capture requests go out ``lead`` seconds before each demand instant (the cameras arm a trigger
for the instant itself); from then on the demand's cameras hold still. Once the demand instant
has passed, the demand is serviced.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from activesurv_dispatch.planner import Demand, Plan, Role
from activesurv_dispatch.sensors import Setup

Array = NDArray[np.float64]


@dataclass(frozen=True)
class StageCommand:
    camera_id: str
    joint_names: tuple[str, ...]
    positions: Array
    max_velocities: Array
    arrival_time: float


@dataclass(frozen=True)
class Capture:
    """A capture to request: the demand and its fusion subset."""

    demand: Demand
    cameras: tuple[str, ...]


class MotionController:
    """Turns plans into stage commands, holding cameras still while they capture."""

    def __init__(
        self, setup: Setup, linear_deadband: float = 2e-4, rotary_deadband: float = 5e-4
    ) -> None:
        self.setup = setup
        self.deadband = {
            s.camera_id: np.array(
                [linear_deadband] * (1 if s.has_linear else 0) + [rotary_deadband]
            )
            for s in setup.sensors
        }
        self._last: dict[str, Array] = {}
        self.holding: set[str] = set()

    def commands(self, plan: Plan, demands: dict[int, Demand]) -> list[StageCommand]:
        out = []
        for s in self.setup.sensors:
            a = plan.assignments.get(s.camera_id)
            if a is None or not s.moves or s.camera_id in self.holding or a.role is Role.IDLE:
                continue
            last = self._last.get(s.camera_id)
            if last is not None and np.all(np.abs(a.desired - last) <= self.deadband[s.camera_id]):
                continue
            self._last[s.camera_id] = a.desired.copy()
            d = demands.get(a.demand_index)
            out.append(
                StageCommand(
                    s.camera_id,
                    s.joint_names,
                    a.desired.copy(),
                    np.array([lim.max_velocity for lim in s.limits]),
                    d.time if d is not None else 0.0,
                )
            )
        return out

    def park(self, initial: dict[str, Array], now: float) -> list[StageCommand]:
        """Send every idle moving camera back to its initial pose (no object to survey)."""
        out = []
        for s in self.setup.sensors:
            q = initial.get(s.camera_id)
            if q is None or not s.moves or s.camera_id in self.holding:
                continue
            last = self._last.get(s.camera_id)
            if last is not None and np.all(np.abs(q - last) <= self.deadband[s.camera_id]):
                continue
            self._last[s.camera_id] = np.asarray(q, dtype=np.float64).copy()
            out.append(
                StageCommand(
                    s.camera_id,
                    s.joint_names,
                    self._last[s.camera_id].copy(),
                    np.array([lim.max_velocity for lim in s.limits]),
                    now,
                )
            )
        return out

    def forget(self, camera_id: str) -> None:
        """Send this camera's next goal even if unchanged (e.g. its stage node restarted)."""
        self._last.pop(camera_id, None)


class CaptureScheduler:
    """Decides when to request each demand's capture and when it is serviced."""

    def __init__(self, lead: float = 0.3) -> None:
        self.lead = lead
        self.requested: dict[int, Capture] = {}
        self.serviced: set[int] = set()

    def due(
        self,
        now: float,
        plan: Plan,
        demands: dict[int, Demand],
        informed: float = math.inf,
        grace: float = 0.0,
    ) -> Capture | None:
        """The capture to request now, if the first demand is within ``lead`` of its instant.

        ``informed``: the time of the overhead fix behind ``plan``; a request waits (at most
        ``grace`` s) for a plan informed at or after ``lead`` before the instant.
        """
        j = plan.first_index
        if j < 0 or j in self.requested or j not in demands:
            return None
        d = demands[j]
        start = d.time - self.lead
        if now < start or (informed < start - 1e-9 and now < start + grace):
            return None
        capture = Capture(d, tuple(plan.assigned()))
        self.requested[j] = capture
        return capture

    def missed(self, now: float, demands: dict[int, Demand]) -> list[Capture]:
        """Demands whose instant passed without a capture request: requested now with no
        cameras, so that fusion answers them with an explicit failure instead of silence."""
        out = []
        for j, d in sorted(demands.items()):
            if j not in self.requested and d.time <= now:
                c = Capture(d, ())
                self.requested[j] = c
                out.append(c)
        return out

    def in_flight(self) -> bool:
        """A capture was requested whose instant has not passed yet."""
        return any(j not in self.serviced for j in self.requested)

    def prune(self, before: float) -> list[int]:
        """Forget demands whose instant is before ``before``; returns their indices."""
        old = [j for j, c in self.requested.items() if c.demand.time < before]
        for j in old:
            del self.requested[j]
            self.serviced.discard(j)
        return old

    def newly_serviced(self, now: float) -> list[Capture]:
        """Requested demands whose instant has passed (their data are being acquired)."""
        done = [
            c for j, c in self.requested.items() if j not in self.serviced and now >= c.demand.time
        ]
        self.serviced.update(c.demand.index for c in done)
        return done
