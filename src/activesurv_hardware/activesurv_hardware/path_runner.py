"""The xy table on a real controller: an experiment's path streamed as short straight moves,
and the truth read back from the positions the controller reports.

GRBL plans a queue of moves; a path sent as one long list would run ahead of the clock, and
one sent late would stall. The runner sends, every ``segment`` seconds of run time ``t``, one
straight move to the path's point ``lead`` seconds ahead at the path's speed there, so the
controller's queue holds about ``lead / segment`` moves and the carriage follows the path's
timing. Before ``start_time`` it parks the carriage at the path's start (at ``approach_speed``);
after the end it sends nothing more.

Truth, as in the paper ("the true target position as measured by the motion controller"): each
position the controller reports, with the stamp of the poll, gives the object's state (top and
side markers, normal, velocity from successive reports) through the object model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from activesurv_common.object_geometry import ObjectGeometry
from activesurv_hardware.errors import HardwareError
from activesurv_sim.stream import ObjectStream
from activesurv_sim.xytable import PARKED, ObjectState, TimedPath, object_state

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TableMove:
    """One straight move of the carriage: to (x, y) at ``speed`` along the line (m, m/s)."""

    x: float
    y: float
    speed: float


class PathRunner:
    """Which move to send at each instant of the run (seconds since the run's time origin)."""

    def __init__(
        self,
        path: TimedPath,
        start_time: float,
        segment: float = 0.1,
        lead: float = 0.2,
        approach_speed: float = 0.05,
        min_speed: float = 1e-4,
    ) -> None:
        if not (segment > 0.0 and lead >= segment and approach_speed > 0.0):
            raise HardwareError('need segment > 0, lead >= segment and approach_speed > 0')
        self.path = path
        self.start_time = float(start_time)
        self.segment = float(segment)
        self.lead = float(lead)
        self.approach_speed = float(approach_speed)
        self.min_speed = float(min_speed)
        self._sent_until = -math.inf

    @property
    def end_time(self) -> float:
        return self.start_time + self.path.duration

    def move(self, t: float) -> TableMove | None:
        """The move to send at run time ``t``, or None (nothing new to send now)."""
        if t < self.start_time - self.lead:
            if self._sent_until > -math.inf:
                return None
            self._sent_until = -1e18  # the approach is sent once
            p = self.path.position(0.0)
            return TableMove(float(p[0]), float(p[1]), self.approach_speed)
        tau = t - self.start_time + self.lead  # path time the move ends at
        tau = min(tau, self.path.duration)
        if tau <= self._sent_until + 1e-9:
            return None
        if tau - max(self._sent_until, 0.0) < self.segment - 1e-9 and tau < self.path.duration:
            return None
        begin = max(self._sent_until, 0.0)
        a, b = self.path.position(begin), self.path.position(tau)
        speed = float(np.linalg.norm(b - a)) / max(tau - begin, 1e-6)
        self._sent_until = tau
        return TableMove(float(b[0]), float(b[1]), max(speed, self.min_speed))

    def finished(self, t: float) -> bool:
        return t >= self.end_time


class TruthFromController:
    """The object's state from the carriage positions the table controller reports."""

    def __init__(self, model: ObjectGeometry) -> None:
        self.model = model
        self._last: tuple[float, Array] | None = None

    def state(self, t: float, xy: Array, present: bool = True) -> ObjectState:
        """The state at ``t`` (the poll's stamp) with the carriage reported at ``xy``; with no
        object on the table (``present`` False) parked out of every view, as the simulator has
        it."""
        if not present:
            self._last = None
            return object_state(self.model, PARKED, np.zeros(2), False, present=False)
        p = np.asarray(xy, dtype=np.float64)[:2]
        v = np.zeros(2)
        if self._last is not None and t > self._last[0]:
            v = (p - self._last[1]) / (t - self._last[0])
        self._last = (t, p)
        return object_state(self.model, p, v, bool(np.linalg.norm(v) > 1e-4))


class StreamRunner:
    """A surveillance session's objects on a real table, one after another.

    Each pass of the stream (:class:`~activesurv_sim.stream.ObjectStream`) is streamed as a
    :class:`PathRunner` from its entry; between passes the carriage goes to the next pass's
    start at ``return_speed``, and no object is on the table as far as anything is told (a cell
    takes the part off at the end and puts the next one on at the start).
    """

    def __init__(
        self,
        stream: ObjectStream,
        segment: float = 0.1,
        lead: float = 0.2,
        return_speed: float = 0.1,
    ) -> None:
        self.stream = stream
        self.segment, self.lead, self.return_speed = segment, lead, return_speed
        self._runners: dict[int, PathRunner] = {}

    def present(self, t: float) -> bool:
        """Whether an object is on the table at ``t``."""
        return self.stream.pass_at(t) is not None

    def move(self, t: float) -> TableMove | None:
        p = self.stream.pass_at(t + self.lead)
        if p is None:
            p = next(q for q in self.stream.passes if q.entered > t)
        runner = self._runners.get(p.id)
        if runner is None:
            runner = PathRunner(p.path, p.entered, self.segment, self.lead, self.return_speed)
            self._runners = {p.id: runner}  # the pass before is done
        return runner.move(t)

    def finished(self, t: float) -> bool:
        return False  # a session runs until it is stopped
