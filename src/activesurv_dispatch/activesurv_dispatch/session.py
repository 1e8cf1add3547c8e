"""The dispatcher's session core: horizon, stage states and imager beats in; goals, capture
requests and missed demands out, on a ``tick(now)`` clock.

It owns the planner (assignment, preassignment, replanning), the motion controller and the
capture scheduler, and the liveness rule: a camera whose stage state is older than
``camera_timeout``, or whose imager has beaten before and then fell silent for as long, is taken
out of dispatching (its frozen slots are refilled from spare cameras) and put back when both
are heard again. The ``dispatcher`` node and lockstep mode drive this same object, so the two
modes cannot drift apart.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.motion import Capture, CaptureScheduler, MotionController, StageCommand
from activesurv_dispatch.planner import Demand, DispatchPlanner, Plan
from activesurv_dispatch.sensors import Setup

Array = NDArray[np.float64]
FORGET_AFTER = 60.0  # s after its instant a serviced demand is forgotten


@dataclass(frozen=True)
class DispatcherConfig:
    """Dispatching settings (``config/dispatcher.yaml``).

    Attributes:
        k: fusion subset size.
        rho: replanning box, in prediction sigmas (paper Section II-D).
        capture_lead: s before a demand instant to send its capture request.
        settle_time: s a camera must be still before the instant.
        camera_timeout: s without stage state or imager heartbeat before a camera is dropped.
        capture_grace: s past ``capture_lead`` a capture request may wait for the prediction
            of the overhead frame taken at or after that moment (the one lockstep decides on).
        capture_hold: s past the demand instant its cameras still hold still: a free-running
            camera's frame nearest the instant lies up to half a frame period after it, and
            the stage state promised for the instant then holds for that frame too (0: the
            frame is exposed at the instant, as a triggered or simulated camera's).
        replan_quiet: s past a serviced demand's instant before its freed cameras are
            planned (0: at once, as lockstep does). The instant's frames are imaged and fused
            in its first milliseconds; a plan computed then (5-10 ms of CPU) would queue them
            on a busy host, and the next demand is seconds away.
    """

    k: int = 3
    rho: float = 1.0
    capture_lead: float = 0.3
    settle_time: float = 0.1
    camera_timeout: float = 0.5
    capture_grace: float = 0.1
    capture_hold: float = 0.0
    replan_quiet: float = 0.0

    @classmethod
    def from_parameters(cls, values: Mapping[str, object]) -> DispatcherConfig:
        """From the ``dispatcher`` node's parameters (the same names)."""
        return cls(**{f.name: type(getattr(cls, f.name))(values[f.name]) for f in fields(cls)})


BLUR_SAID = 0.1  # a view's visibility its predicted blur costs, from which the log says so


def _blurred(plan: Plan, camera_id: str) -> str:
    """`` (blur -N %)`` when the predicted blur costs the camera's view ``BLUR_SAID`` or more
    of its visibility (why a view lost to a sharper one), else nothing."""
    loss = dict(plan.blur_loss).get(camera_id, 0.0)
    return f' (blur -{100.0 * loss:.0f} %)' if loss >= BLUR_SAID else ''


@dataclass
class Outputs:
    """What one input or tick produced, for the caller to publish.

    Attributes:
        goals: stage commands to send.
        captures: capture requests to send now (their cameras hold still until the instant).
        missed: demands whose instant passed with no assignment (requests with no cameras).
        serviced: captures whose instant has passed (lockstep acquires their frames now).
        plan: the newest plan, when planning ran.
        events: (level, text) lines for the log: 'info' or 'warning'.
    """

    goals: list[StageCommand] = field(default_factory=list)
    captures: list[Capture] = field(default_factory=list)
    missed: list[Capture] = field(default_factory=list)
    serviced: list[Capture] = field(default_factory=list)
    plan: Plan | None = None
    events: list[tuple[str, str]] = field(default_factory=list)

    def merge(self, other: Outputs) -> None:
        self.goals += other.goals
        self.captures += other.captures
        self.missed += other.missed
        self.serviced += other.serviced
        self.plan = other.plan or self.plan
        self.events += other.events


class Dispatcher:
    """One dispatching session over a rolling horizon."""

    def __init__(self, setup: Setup, model: SensorModel, config: DispatcherConfig) -> None:
        self.setup = setup
        self.config = config
        self.planner = DispatchPlanner(setup, model, config.k, config.rho, config.settle_time)
        self.motion = MotionController(setup)
        self.scheduler = CaptureScheduler(config.capture_lead)
        self.joints: dict[str, Array] = {}
        self.joint_stamp: dict[str, float] = {}
        self.beat_stamp: dict[str, float] = {}
        self.down: dict[str, str] = {}  # camera -> why it is out of dispatching
        self.faults: dict[str, str] = {}  # camera -> what its stage controller reports
        self.demands: dict[int, Demand] = {}
        self.horizon: list[Demand] = []
        self.plan: Plan | None = None
        self.plan_ms: list[float] = []
        self.counts: Counter[str] = Counter()
        self._manoeuvres = 0
        self._announced: dict[int, tuple[str, ...]] = {}
        self.held_until: dict[str, float] = {}  # camera: run time its capture hold ends
        self.horizon_stamp = -math.inf  # the overhead fix time behind the current horizon
        self._stalls: dict[str, float] = {}  # signal -> when every camera fell silent
        self._stall_over: dict[str, float] = {}  # signal -> when the stall ended
        self._replan_at = math.inf  # a replan put off past a demand's instant (replan_quiet)

    # -- inputs ----------------------------------------------------------------------------
    def on_joints(self, camera_id: str, q: ArrayLike, now: float) -> Outputs:
        """A stage state of ``camera_id`` (positions in its joint order) heard at ``now``."""
        v = np.asarray(q, dtype=np.float64).reshape(-1)
        names = self.setup.sensor(camera_id).joint_names
        if v.shape != (len(names),) or not np.all(np.isfinite(v)):
            self.counts['bad_joint_states'] += 1
            return Outputs()
        self.joints[camera_id] = v
        self._resumed('stage state', self.joint_stamp, now)
        self.joint_stamp[camera_id] = now
        return self._check_alive(now) if camera_id in self.down else Outputs()

    def on_beat(self, camera_id: str, now: float) -> None:
        """The imager of ``camera_id`` beat at ``now``."""
        self._resumed('imager heartbeat', self.beat_stamp, now)
        self.beat_stamp[camera_id] = now

    def _resumed(self, signal: str, stamps: dict[str, float], now: float) -> None:
        """One camera's ``signal`` heard after every live camera's was silent for longer than
        ``camera_timeout``, and no check saw the silence: this process stalled (at start-up, a
        busy core: 0.5 s in one run) and the others' messages are queued behind this one. The
        stall ends now: they get ``camera_timeout`` to be heard before any is judged."""
        ages = [now - t for c, t in stamps.items() if c not in self.down]
        if len(ages) > 1 and min(ages) > self.config.camera_timeout and signal not in self._stalls:
            self._stall_over[signal] = now
            self.counts['stalls'] += 1

    def on_stage_fault(self, camera_id: str, fault: str, now: float) -> Outputs:
        """What the stage controller of ``camera_id`` reports: a fault (a stall, the controller
        lost, the e-stop) takes the camera out of dispatching; '' (cleared) lets it back."""
        if camera_id not in self.joint_stamp or self.faults.get(camera_id, '') == fault:
            return Outputs()
        if fault:
            self.faults[camera_id] = fault
        else:
            self.faults.pop(camera_id, None)
        return self._check_alive(now)

    def set_horizon(
        self,
        demands: Sequence[Demand],
        now: float,
        dropped: int = 0,
        manoeuvres: int = 0,
        stamp: float | None = None,
    ) -> Outputs:
        """A new rolling horizon; ``dropped`` malformed demands were left out of it;
        ``manoeuvres``: the predictor's manoeuvre count of this track (a change replans);
        ``stamp``: the time of the overhead fix it was predicted from (default ``now``)."""
        self.horizon_stamp = now if stamp is None else stamp
        self.counts['bad_demands'] += dropped
        manoeuvred = manoeuvres != self._manoeuvres and manoeuvres > 0
        self._manoeuvres = manoeuvres
        if manoeuvred:
            self.planner.manoeuvre()
            self.counts['manoeuvres'] += 1
        # Continuous surveillance: a demand of an object that vanished from the horizon before
        # its capture request (the object left, or its point left the demand region) is
        # withdrawn, not failed. An experiment's demands are promised for good.
        keep = {d.index for d in demands}
        for j, d in list(self.demands.items()):
            if (
                d.object_id
                and j not in keep
                and j not in self.scheduler.requested
                and d.time > now
            ):
                del self.demands[j]
                self.counts['withdrawn_demands'] += 1
        for d in demands:
            self.demands[d.index] = d
        self.horizon = list(demands)
        out = self._replan(now)
        if manoeuvred:
            out.events.append(('info', f'the object manoeuvred (t={now:.2f} s): replanning'))
        out.merge(self._request_due(now))
        return out

    # -- the work --------------------------------------------------------------------------
    def _replan(self, now: float) -> Outputs:
        self._replan_at = math.inf  # whatever was put off is planned now
        if not self.joints:
            return Outputs()
        t0 = time.perf_counter()
        plan = self.planner.plan(now, self.horizon, self.joints)
        self.plan_ms = [*self.plan_ms[-199:], 1e3 * (time.perf_counter() - t0)]
        self.plan = plan
        out = Outputs(plan=plan)
        if plan.replanned:
            out.events.append(
                ('info', f'replanned demand {plan.first_index}: the prediction moved')
            )
        assigned = tuple(plan.assigned())
        if plan.first_index >= 0 and self._announced.get(plan.first_index) != assigned:
            self._announced[plan.first_index] = assigned
            ranking = ', '.join(f'{c} {v:.3g}{_blurred(plan, c)}' for c, v in plan.ranking)
            heard = sorted(c for c in self.joints if c not in self.planner.excluded)
            out.events.append(
                (
                    'info',
                    f'demand {plan.first_index} assigned {list(assigned)} (t={now:.2f} s; '
                    f'visibility {ranking}; cameras heard {heard})',
                )
            )
        out.goals = self.motion.commands(plan, self.demands)
        if not self.horizon and not self.scheduler.in_flight():
            # No object to survey (between objects): the cameras wait at their initial poses.
            alive = {c: q for c, q in self.setup.initial.items() if c in self.joints}
            out.goals += self.motion.park(
                {c: q for c, q in alive.items() if c not in self.planner.excluded}, now
            )
        self.counts['goals'] += len(out.goals)
        return out

    def _check_alive(self, now: float) -> Outputs:
        """Take cameras whose stage or imager fell silent out of dispatching; re-admit them."""
        timeout = self.config.camera_timeout
        out = Outputs()
        changed = False
        # Every stage (or every imager) silent at once: this node or that transport stalled
        # (a busy process sees its timer before the messages queued behind it), not all of
        # them died. Dropping them all would leave the next demand without a camera, however
        # long it lasts; a camera is judged only while others of its kind are heard. Each
        # signal is judged on its own: stage states stalled together do not hide an imager
        # whose heartbeat stopped while the others' go on.
        stages_stalled = self._stalled('stage state', self.joint_stamp, now, out)
        beats_stalled = self._stalled('imager heartbeat', self.beat_stamp, now, out)
        for cid, stamp in self.joint_stamp.items():
            why = ''
            if cid in self.faults:
                why = f'stage fault: {self.faults[cid]}'
            elif now - stamp > timeout and (cid in self.down or not stages_stalled):
                why = f'no stage state for {timeout:g} s'
            elif (
                cid in self.beat_stamp
                and now - self.beat_stamp[cid] > timeout
                and (cid in self.down or not beats_stalled)
            ):
                why = f'no imager heartbeat for {timeout:g} s'
            elif cid not in self.down and (stages_stalled or beats_stalled):
                continue  # silent with the rest: not judged until the stall is over
            if why and self.down.get(cid) not in (None, why):
                self.down[cid] = why  # already out: the newer reason
            elif why and cid not in self.down:
                self.down[cid] = why
                self.planner.exclude(cid)
                self.counts['cameras_lost'] += 1
                out.events.append(
                    ('warning', f'{cid}: {why}; dispatching without it (t={now:.2f} s)')
                )
                changed = True
            elif not why and cid in self.down:
                del self.down[cid]
                self.planner.include(cid)
                self.motion.forget(cid)
                self.counts['cameras_back'] += 1
                out.events.append(('info', f'{cid} is back: dispatching it again (t={now:.2f} s)'))
                changed = True
        if changed:
            out.merge(self._replan(now))
        return out

    def _stalled(self, signal: str, stamps: dict[str, float], now: float, out: Outputs) -> bool:
        """Whether every live camera's ``signal`` went silent together (or did so less than
        ``camera_timeout`` ago: the others' messages are still on their way); says when a
        stall begins and ends."""
        timeout = self.config.camera_timeout
        ages = [now - t for c, t in stamps.items() if c not in self.down]
        silent = len(ages) > 1 and min(ages) > timeout
        began = self._stalls.get(signal)
        if silent and began is None:
            self._stalls[signal] = now - min(ages)
            self._stall_over.pop(signal, None)
            self.counts['stalls'] += 1
            out.events.append(
                (
                    'warning',
                    f'every {signal} silent at once for {min(ages):.2f} s (t={now:.2f} s): '
                    'this machine or the transport stalled; no camera is dropped for it',
                )
            )
        elif not silent and began is not None:
            del self._stalls[signal]
            self._stall_over[signal] = now
            out.events.append(('info', f'{signal}s heard again after {now - began:.2f} s'))
        over = self._stall_over.get(signal)
        if over is not None and now - over > timeout:
            del self._stall_over[signal]
            over = None
        return silent or over is not None

    def tick(self, now: float, serviced_until: float | None = None) -> Outputs:
        """Liveness, due capture requests, missed demands and serviced demands at ``now``.

        Args:
            now: the current time.
            serviced_until: report captures whose instant falls before this time as serviced
                (default ``now``); lockstep looks ahead to the end of its step.
        """
        out = self._check_alive(now)
        if now >= self._replan_at:
            out.merge(self._replan(now))
        out.merge(self._request_due(now))
        for missed in self.scheduler.missed(now, self.demands):
            self.planner.serviced(missed.demand.index)
            self.counts['missed_demands'] += 1
            out.missed.append(missed)
            out.events.append(
                (
                    'warning',
                    f'demand {missed.demand.index} passed with no camera assigned; '
                    'reported as a failure',
                )
            )
        until = now if serviced_until is None else serviced_until
        serviced = self.scheduler.newly_serviced(until)
        for done in serviced:
            self.planner.serviced(done.demand.index)
            end = done.demand.time + self.config.capture_hold
            waiting = {  # cameras of captures requested and not yet serviced: held on
                c
                for j, cap in self.scheduler.requested.items()
                if j not in self.scheduler.serviced
                for c in cap.cameras
            }
            self.held_until.update({c: end for c in done.cameras if c not in waiting})
            out.serviced.append(done)
        released = [c for c, end in self.held_until.items() if until >= end]
        for c in released:
            del self.held_until[c]
        self.motion.holding.difference_update(released)
        if serviced or released:  # the next demand first, the released cameras free again
            quiet = max((d.demand.time for d in serviced), default=-math.inf)
            quiet += self.config.replan_quiet
            if now < quiet:
                self._replan_at = min(self._replan_at, quiet)  # on the first tick from then
            else:
                out.merge(self._replan(now))
        # A continuous session runs for hours: demands long past are forgotten.
        for j in self.scheduler.prune(now - FORGET_AFTER):
            self.demands.pop(j, None)
            self._announced.pop(j, None)
        return out

    def _request_due(self, now: float) -> Outputs:
        """The first demand's capture request, once it is due: ``capture_lead`` before its
        instant and planned on the prediction of an overhead fix taken by then (or, with no
        such prediction, ``capture_grace`` later): its camera set is final from here on."""
        out = Outputs()
        if self.plan is None:
            return out
        capture = self.scheduler.due(
            now, self.plan, self.demands, self.horizon_stamp, self.config.capture_grace
        )
        if capture is not None:
            self.planner.close(capture.demand.index)
            self.motion.holding.update(capture.cameras)
            for c in capture.cameras:  # held until this demand is serviced (and its hold)
                self.held_until[c] = math.inf
            self.counts['captures'] += 1
            out.captures.append(capture)
            out.events.append(
                (
                    'info',
                    f'capture demand {capture.demand.index} at {capture.demand.time:.2f} s '
                    f'with {list(capture.cameras)}',
                )
            )
        return out

    def status(self) -> dict[str, object]:
        """Diagnostics values."""
        ms = self.plan_ms or [math.nan]
        values: dict[str, object] = dict(self.counts)
        values.update(
            plan_ms_median=f'{float(np.median(ms)):.2f}',
            replans=self.planner.replans,
            cameras_with_state=sorted(self.joints),
            cameras_down=sorted(self.planner.excluded),
            why_down=dict(self.down),
            serving=self.plan.first_index if self.plan else -1,
        )
        return values
