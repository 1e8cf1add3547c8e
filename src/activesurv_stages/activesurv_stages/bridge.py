"""The serial bridge's worker: one thread owns the controller, the node only talks to it.

* Goals are checked against the soft limits when they are submitted, and again in raw units
  before anything is written to the port. A goal outside the limits is refused with a reason;
  nothing is sent.
* The worker polls positions at ``poll_rate`` and keeps the latest snapshot (SI units).
* Recovery: a communication error (unplugged port, silence, a reset mid-reply) closes the port
  and reconnects every ``reconnect_period`` until it works. An axis that reports no reference
  position (first connection, or after a controller reset) is homed only when asked
  (``home_on_connect``), and the last goal is then sent again; otherwise its goals are refused
  with a reason. Garbage lines are counted and skipped by the driver.
* Stopping: :meth:`BridgeWorker.stop_all` sends the protocol's own stop (Zaber ``stop``, GRBL
  feed hold + jog cancel) at once (the worker is woken, it does not wait for the next poll);
  :meth:`BridgeWorker.set_estop` does the same and refuses every goal while the e-stop is
  raised; :meth:`BridgeWorker.shutdown` stops the axes before it closes the port.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

from activesurv_stages.config import AxisConfig
from activesurv_stages.drivers import AxisReport, StageDriver
from activesurv_stages.errors import (
    CommunicationError,
    ControllerRejectedError,
    LimitError,
    ProtocolError,
    StageError,
)


class LinkState(Enum):
    DISCONNECTED = 'disconnected'
    HOMING = 'homing'
    READY = 'ready'


@dataclass(frozen=True)
class Goal:
    joint: str
    position: float  # SI
    velocity: float | None  # SI/s, None: the axis maximum
    raw_position: float
    raw_speed: float


@dataclass
class Snapshot:
    """The bridge's latest view (SI). ``stamp`` is ``time.monotonic()`` of the poll."""

    state: LinkState = LinkState.DISCONNECTED
    stamp: float = 0.0
    wall: float = 0.0  # time.time() when the controller reported (mid-point of the poll)
    positions: dict[str, float] = field(default_factory=dict)
    velocities: dict[str, float] = field(default_factory=dict)
    statuses: dict[str, str] = field(default_factory=dict)
    last_error: str = ''
    counters: dict[str, int] = field(default_factory=dict)


class BridgeWorker:
    """Runs a :class:`StageDriver` in a thread for the given axes."""

    def __init__(
        self,
        driver_factory: Callable[[], StageDriver],
        axes: list[AxisConfig],
        poll_rate: float = 20.0,
        reconnect_period: float = 1.0,
        home_on_connect: bool = False,
    ) -> None:
        if not axes:
            raise StageError('a bridge needs at least one axis')
        self.factory = driver_factory
        self.axes = {a.joint: a for a in axes}
        self.poll_period = 1.0 / poll_rate
        self.reconnect_period = reconnect_period
        self.home_on_connect = home_on_connect
        self._lock = threading.Lock()
        self._pending: dict[str, Goal] = {}
        self._sent_since_poll = False  # goals went out after the last poll's reports
        self._last_goal: dict[str, Goal] = {}
        self._snap = Snapshot()
        self._counters = {
            'connects': 0,
            'comm_errors': 0,
            'rejected_goals': 0,
            'limit_rejections': 0,
            'homings': 0,
            'goals_sent': 0,
            'garbage_lines': 0,
            'protocol_errors': 0,
            'refused_unreferenced': 0,
        }
        self._stop = threading.Event()
        self._wake = threading.Event()  # a stop request cuts the poll period short
        self._estop = False
        self._stops_sent = 0  # stop commands written to the controller
        self._thread: threading.Thread | None = None
        self._driver: StageDriver | None = None
        self._stop_request: set[str] = set()
        self._garbage_base = 0  # garbage lines seen by earlier connections

    # -- API for the node -------------------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name='stage-bridge', daemon=True)
        self._thread.start()

    def shutdown(self, timeout: float = 3.0) -> None:
        """Stop the axes with the protocol's stop, then close the port (every way out of a
        bridge comes here: shutdown, SIGINT, SIGTERM, a gone orchestrator)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)
        if self._driver is not None:
            self._send_stops(set(self.axes))
            self._driver.close()

    def stop_all(self) -> None:
        """Drop every queued goal and stop every axis at once."""
        with self._lock:
            self._pending.clear()
            self._stop_request.update(self.axes)
        self._wake.set()

    def set_estop(self, raised: bool) -> None:
        """Raise (stop every axis, refuse goals) or lower the e-stop."""
        with self._lock:
            self._estop = raised
        if raised:
            self.stop_all()

    @property
    def estop(self) -> bool:
        with self._lock:
            return self._estop

    def standing_still(self) -> bool:
        """Whether the last poll found every axis idle (not moving)."""
        with self._lock:
            s = self._snap
            return s.state is LinkState.READY and all(
                s.statuses.get(j) in ('idle', 'fault') for j in self.axes
            )

    def settled(self) -> bool:
        """Standing still with no goal queued or sent since the last poll: the axes stay
        where that poll found them until a new goal comes."""
        still = self.standing_still()
        with self._lock:
            return still and not self._pending and not self._sent_since_poll

    def submit_goal(self, joint: str, position: float, velocity: float | None = None) -> Goal:
        """Queue a goal (the newest goal per joint wins).

        Raises:
            LimitError: outside the soft limits or invalid; nothing is queued or sent.
            StageError: for an unknown joint.
        """
        axis = self.axes.get(joint)
        if axis is None:
            raise StageError(f'unknown joint {joint!r}; this bridge drives {list(self.axes)}')
        if self.estop:
            raise StageError(f'{joint}: the e-stop is raised: goal refused')
        try:
            raw_p, raw_v = axis.checked_goal(position, velocity)
        except LimitError:
            with self._lock:
                self._counters['limit_rejections'] += 1
            raise
        goal = Goal(joint, position, velocity, raw_p, raw_v)
        with self._lock:
            self._pending[joint] = goal
        return goal

    def submit_goals(self, items: list[tuple[str, float, float | None]]) -> list[str]:
        """Queue the goals of one message together (a controller that moves several axes sends
        them as one straight move); each refused goal is reported, the others still queued.

        Returns:
            The reasons of the refused goals (nothing of them is queued or sent).
        """
        refused: list[str] = []
        checked: list[Goal] = []
        if self.estop:
            return [
                f'{j}: the e-stop is raised: goal refused (activesurv stop --release)'
                for j, _, _ in items
            ]
        for joint, position, velocity in items:
            axis = self.axes.get(joint)
            if axis is None:
                refused.append(f'unknown joint {joint!r}; this bridge drives {list(self.axes)}')
                continue
            try:
                raw_p, raw_v = axis.checked_goal(position, velocity)
            except LimitError as exc:
                with self._lock:
                    self._counters['limit_rejections'] += 1
                refused.append(str(exc))
                continue
            checked.append(Goal(joint, position, velocity, raw_p, raw_v))
        with self._lock:
            for goal in checked:
                self._pending[goal.joint] = goal
        return refused

    def request_stop(self, joint: str) -> None:
        with self._lock:
            self._stop_request.add(joint)
            self._pending.pop(joint, None)
        self._wake.set()

    def snapshot(self) -> Snapshot:
        with self._lock:
            s = self._snap
            return Snapshot(
                s.state,
                s.stamp,
                s.wall,
                dict(s.positions),
                dict(s.velocities),
                dict(s.statuses),
                s.last_error,
                {**self._counters, 'stops_sent': self._stops_sent},
            )

    # -- the thread -------------------------------------------------------------------------
    def _set(self, **kwargs: object) -> None:
        with self._lock:
            for k, v in kwargs.items():
                setattr(self._snap, k, v)

    def _error(self, text: str, counter: str) -> None:
        with self._lock:
            self._snap.last_error = text
            self._counters[counter] += 1

    def _run(self) -> None:
        while not self._stop.is_set():
            if self._driver is None and not self._connect():
                self._stop.wait(self.reconnect_period)
                continue
            try:
                self._cycle()
            except CommunicationError as exc:
                self._error(f'communication lost: {exc}', 'comm_errors')
                self._drop_link()
                self._stop.wait(self.reconnect_period)
            except ProtocolError as exc:
                self._error(f'protocol error: {exc}', 'protocol_errors')
            except Exception as exc:
                self._error(f'unexpected {type(exc).__name__}: {exc}', 'comm_errors')
                self._drop_link()
                self._stop.wait(self.reconnect_period)
            self._wake.wait(self.poll_period)
            self._wake.clear()

    def _drop_link(self) -> None:
        if self._driver is not None:
            self._garbage_base += self._driver.garbage_lines
            self._driver.close()
        self._driver = None
        self._set(state=LinkState.DISCONNECTED)

    def _connect(self) -> bool:
        try:
            driver = self.factory()
            found = driver.connect()
            missing = sorted({a.axis for a in self.axes.values()} - set(found))
            if missing:
                driver.close()
                raise StageError(f'axes {missing} not found on the controller (found {found})')
        except StageError as exc:
            self._error(f'connect failed: {exc}', 'comm_errors')
            return False
        self._driver = driver
        with self._lock:
            self._counters['connects'] += 1
        self._set(state=LinkState.HOMING if self.home_on_connect else LinkState.READY)
        return True

    def _reports(self) -> dict[str, AxisReport]:
        assert self._driver is not None
        by_axis = {r.axis: r for r in self._driver.poll()}
        with self._lock:
            self._counters['garbage_lines'] = self._garbage_base + self._driver.garbage_lines
        return {j: by_axis[a.axis] for j, a in self.axes.items() if a.axis in by_axis}

    def _send_stops(self, joints: set[str]) -> None:
        """The protocol's stop for the axes of ``joints`` (one per controller axis); a failure
        is recorded, the other axes are still stopped."""
        if self._driver is None:
            return
        for axis in sorted({self.axes[j].axis for j in joints if j in self.axes}):
            try:
                self._driver.stop(axis)
            except (StageError, OSError) as exc:
                self._error(f'stop of axis {axis} failed: {exc}', 'comm_errors')
                continue
            with self._lock:
                self._stops_sent += 1

    def _cycle(self) -> None:
        driver = self._driver
        assert driver is not None
        with self._lock:  # stops first, before the poll's round trip
            stops = set(self._stop_request)
            self._stop_request.clear()
        self._send_stops(stops)
        asked = time.time()
        reports = self._reports()
        told = 0.5 * (asked + time.time())  # the controller answered about then
        unhomed = [j for j, r in reports.items() if r.needs_home]
        if unhomed and self.home_on_connect:
            self._home(unhomed)
            reports = self._reports()
            unhomed = [j for j, r in reports.items() if r.needs_home]
        now = time.monotonic()
        with self._lock:
            prev, prev_t = dict(self._snap.positions), self._snap.stamp
            for j, r in reports.items():
                p = self.axes[j].to_si(r.position)
                dt = now - prev_t
                v = (p - prev[j]) / dt if j in prev and dt > 1e-6 else 0.0
                self._snap.velocities[j] = v if r.status == 'busy' else 0.0
                self._snap.positions[j] = p
                self._snap.statuses[j] = r.status
            self._snap.stamp = now
            self._snap.wall = told
            if self._snap.state is not LinkState.READY and not unhomed:
                self._snap.state = LinkState.READY
            goals = [] if self._estop else list(self._pending.values())
            self._pending.clear()
            self._sent_since_poll = bool(goals)
        refused = [g for g in goals if g.joint in unhomed]
        together = getattr(driver, 'move_together', None)
        if together is not None and len(goals) - len(refused) > 1 and not refused:
            # One controller moving several axes (the xy table): one straight-line move, not
            # one axis after the other in the controller's planner.
            self._send_together(goals)
            return
        for i, goal in enumerate(goals):
            if goal.joint in unhomed:  # never homed without being asked: refuse, send nothing
                self._error(
                    f'{goal.joint} has no reference position: goal refused (home it: '
                    'stage_bridge home_on_connect:=true)',
                    'refused_unreferenced',
                )
                continue
            try:
                self._send(goal)
            except (CommunicationError, ProtocolError):
                # The link failed mid-send: keep this goal and the unsent ones for after the
                # reconnect, unless newer goals arrived meanwhile.
                with self._lock:
                    for g in goals[i:]:
                        self._pending.setdefault(g.joint, g)
                raise

    def _home(self, joints: list[str]) -> None:
        assert self._driver is not None
        self._set(state=LinkState.HOMING)
        for axis in sorted({self.axes[j].axis for j in joints}):
            self._driver.home(axis)
        with self._lock:
            self._counters['homings'] += 1
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and not self._stop.is_set():
            reports = self._reports()
            if all(r.status == 'idle' and not r.needs_home for r in reports.values()):
                break
            self._stop.wait(self.poll_period)
        # The controller lost its goals with its reference: send the last ones again.
        with self._lock:
            for j in joints:
                if j in self._last_goal and j not in self._pending:
                    self._pending[j] = self._last_goal[j]

    def _send_together(self, goals: list[Goal]) -> None:
        assert self._driver is not None
        targets: dict[str, float] = {}
        speeds: list[float] = []
        for goal in goals:
            axis = self.axes[goal.joint]
            si = axis.to_si(goal.raw_position)
            if not (
                math.isfinite(si)
                and axis.limits.min_position - 1e-9 <= si <= axis.limits.max_position + 1e-9
            ):
                self._error(
                    f'{goal.joint}: refused to send a goal outside the limits', 'limit_rejections'
                )
                return
            targets[axis.axis] = goal.raw_position
            if goal.raw_speed is not None:
                speeds.append(goal.raw_speed)
        speed = math.sqrt(sum(v * v for v in speeds)) if speeds else None
        try:
            self._driver.move_together(targets, speed)  # type: ignore[attr-defined]
        except ControllerRejectedError as exc:
            self._error(f'{", ".join(g.joint for g in goals)}: {exc}', 'rejected_goals')
            return
        with self._lock:
            self._counters['goals_sent'] += len(goals)
            for goal in goals:
                self._last_goal[goal.joint] = goal

    def _send(self, goal: Goal) -> None:
        assert self._driver is not None
        axis = self.axes[goal.joint]
        # Belt and braces: the raw goal must map back inside the soft limits.
        si = axis.to_si(goal.raw_position)
        if not (
            math.isfinite(si)
            and axis.limits.min_position - 1e-9 <= si <= axis.limits.max_position + 1e-9
        ):
            self._error(
                f'{goal.joint}: refused to send a goal outside the limits', 'limit_rejections'
            )
            return
        try:
            self._driver.move(axis.axis, goal.raw_position, goal.raw_speed)
        except ControllerRejectedError as exc:
            self._error(f'{goal.joint}: {exc}', 'rejected_goals')
            return
        with self._lock:
            self._counters['goals_sent'] += 1
            self._last_goal[goal.joint] = goal
