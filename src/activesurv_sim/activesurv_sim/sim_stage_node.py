"""The ``sim_stage`` node: a simulated camera stage with the bridge's topics and behaviour.

Subscribes: <camera_id>/stage/goal (activesurv_interfaces/StageGoal); capture_request
    (activesurv_interfaces/CaptureRequest): on the request the stage publishes, stamped the
    demand instant, where its commanded profile puts the axes then (again on every goal that
    changes it before the instant), so the imager has the state at hand when the frame
    arrives; at the instant it publishes its state stamped exactly then (as a controller that
    latches its encoders on the camera's trigger line would) only if that differs; and on
    ``sim/<camera_id>/planned_joint_states`` the same for the simulated camera's rendering
    ahead.
Publishes: <camera_id>/stage/joint_states (sensor_msgs/JointState) at ``publish_rate`` (on
    the simulated clock owner's grid, whatever /clock's rate: ``instants.periodic``) and at the
    demand instants, /diagnostics.
The axes follow the kinematics core on the node's clock (simulated time in experiments) with
the velocity and acceleration caps of the motion class (static, medium, fast). Goals outside the
soft limits, or any goal for a static camera, are refused with a logged reason.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.timer import Timer
from sensor_msgs.msg import JointState

from activesurv_common.ros import diagnostics, local_topics, qos, topics
from activesurv_common.ros.conversions import sec_to_time, time_to_sec
from activesurv_common.ros.fine_clock import FineClock
from activesurv_common.ros.instants import periodic
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_interfaces.msg import CaptureRequest, StageGoal
from activesurv_stages.config import MOTION_CLASSES, motion_class
from activesurv_stages.conversions import goal_items, joint_state, stale_goal
from activesurv_stages.errors import ConfigError, LimitError, StageError
from activesurv_stages.kinematics import AxisLimits, AxisSimulator

PARAMS = (
    Param('camera_id', 'cam1', 'topic prefix'),
    Param('joints', ['cam1_x', 'cam1_yaw'], 'joint names'),
    Param('kinds', ['linear', 'rotary'], 'linear or rotary, per joint'),
    Param('min', [-0.15, -1.5], 'soft limits (m, rad)'),
    Param('max', [0.15, 1.5], 'soft limits (m, rad)'),
    Param('initial', [0.0, 0.0], 'start positions (m, rad)'),
    Param('motion_class', 'fast', 'camera speeds', choices=tuple(sorted(MOTION_CLASSES))),
    Param('publish_rate', 25.0, 'JointState rate (Hz)', minimum=0.5, maximum=1000.0),
)


class SimStageNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('sim_stage', **kwargs)
        declare(self, PARAMS)

        g = self.get_parameter
        self.camera_id = str(g('camera_id').value)
        self.joints = [str(j) for j in g('joints').value]
        kinds = [str(k) for k in g('kinds').value]
        lo, hi, init = (list(g(n).value) for n in ('min', 'max', 'initial'))
        if not (len(self.joints) == len(kinds) == len(lo) == len(hi) == len(init)):
            raise ConfigError('joints, kinds, min, max and initial need the same length')
        self.motion = motion_class(str(g('motion_class').value))
        self._fine = FineClock(self.get_clock(), self)
        now = self._now()
        self.axes: dict[str, AxisSimulator] = {}
        for j, k, a, b, p in zip(self.joints, kinds, lo, hi, init, strict=True):
            v, acc = self.motion.limits(k)
            # A static camera still needs limits for the model; it refuses every goal.
            limits = AxisLimits(float(a), float(b), v or 1e-9, acc or 1e-9)
            self.axes[j] = AxisSimulator(limits, float(p), now)
        self.counts: Counter[str] = Counter()
        self.last_refusal = ''

        # Its camera and imager in its container take the states in process (local_topics).
        states = topics.joint_states(self.camera_id)
        self._pub = local_topics.publisher(self, JointState, states, qos.STATE)
        self._diag = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS)
        self.create_subscription(StageGoal, topics.goal(self.camera_id), self._on_goal, qos.GOAL)
        self._triggers: dict[float, Timer | bool | None] = {}  # None: fired
        self._ahead: dict[float, list[float]] = {}  # instant: positions published for it
        self._planned_pub = self.create_publisher(
            JointState, topics.planned_joint_states(self.camera_id), qos.EVENTS
        )
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS
        )
        # States at its rate on the clock owner's grid, however often /clock ticks.
        self._period = 1.0 / float(g('publish_rate').value)
        self._instants = periodic(self, self._period, self._publish)
        self.create_timer(1.0, self._publish_diagnostics)

    def _now(self) -> float:
        return self._fine.now()  # between /clock ticks too (every other state has none)

    def _refuse(self, text: str) -> None:
        self.counts['refused'] += 1
        self.last_refusal = text
        self.get_logger().warning(text, throttle_duration_sec=2)

    def _on_goal(self, msg: StageGoal) -> None:
        # From the frame it was planned on (its stamp, less than a state period ago), as in
        # lockstep; a real bridge starts it on arrival, 10-20 ms later here.
        now, stamp = self._now(), time_to_sec(msg.header.stamp)
        if (stale := stale_goal(msg, now)) is not None:
            self._refuse(stale)
            return
        now = stamp if now - self._period <= stamp <= now else now
        for joint, position, velocity in goal_items(msg):
            if joint not in self.axes:
                self._refuse(f'goal for unknown joint {joint!r} ignored (have {self.joints})')
                continue
            if not self.motion.moves:
                self._refuse(f'{joint}: the static system does not move; goal ignored')
                continue
            try:
                self.axes[joint].command(now, position, velocity)
                self.counts['accepted'] += 1
            except LimitError as exc:
                self._refuse(f'{joint}: goal refused: {exc}')
        for t in [t for t, timer in self._triggers.items() if timer is not None and t > now]:
            self._publish(t)  # the instant's state as the new profile has it

    def _on_request(self, msg: CaptureRequest) -> None:
        t = time_to_sec(msg.demand_instant)
        now = self._now()
        if self.camera_id not in msg.camera_ids or t in self._triggers or not t > now:
            return
        # At the instant on the clock owner's mapping (not /clock's next tick), else a tick.
        # Not set ahead to sleep to it: the state is stamped with the instant however late
        # this runs, and a sleep here held its camera's frame in their container's one thread
        # (the median latency 9.5 -> 8.9 ms, six pairs of Set A fast runs).
        on_map = self._instants.at(t, lambda: self._trigger(t), exact=False)
        self._triggers[t] = on_map or self.create_timer(t - now, lambda: self._trigger(t))
        self._publish_planned(t)
        self._publish(t)  # where the commanded profile has the axes at the instant

    def _publish_planned(self, t: float) -> None:
        """Where the axes will be at ``t`` if no new goal comes (simulated cameras render
        ahead with it and check against the state published at ``t``)."""
        states = [self.axes[j].state(t) for j in self.joints]
        self._planned_pub.publish(
            joint_state(
                self.joints, [s[0] for s in states], [s[1] for s in states], sec_to_time(t)
            )
        )

    def _trigger(self, t: float) -> None:
        timer = self._triggers.get(t)
        if isinstance(timer, Timer):
            timer.cancel()
            self.destroy_timer(timer)
        # The state at the instant itself, even if this timer fired a tick late (a latched
        # encoder reading), so that camera and imager find a sample stamped exactly t; unless
        # the one published ahead for t holds (no goal since changed it): at the instant that
        # message only woke four processes before the imaging (docs/performance.md).
        at, ahead = min(t, self._now()), self._ahead.pop(t, None)
        if at < t or ahead != self._positions(t):
            self._publish(at)
            self._ahead.pop(t, None)
        self._triggers = {k: v for k, v in self._triggers.items() if k > t - 60.0}
        self._triggers[t] = None

    def _positions(self, t: float) -> list[float]:
        return [self.axes[j].state(t)[0] for j in self.joints]

    def _publish(self, at: float | None = None) -> None:
        now = self._now() if at is None else at
        states = [self.axes[j].state(now) for j in self.joints]
        if now in self._triggers and self._triggers[now] is not None:
            self._ahead[now] = [p for p, _ in states]  # published ahead for the instant now
        self._pub.publish(
            joint_state(
                self.joints, [s[0] for s in states], [s[1] for s in states], sec_to_time(now)
            )
        )

    def _publish_diagnostics(self) -> None:
        values: dict[str, Any] = {**self.counts, 'last_refusal': self.last_refusal}
        s = diagnostics.status(
            f'activesurv/sim_stage/{self.camera_id}',
            self.camera_id,
            f'{self.motion.name} system, {self.counts["accepted"]} goals accepted',
            values,
            diagnostics.WARN if self.counts['refused'] else diagnostics.OK,
        )
        self._diag.publish(diagnostics.array(sec_to_time(self._now()), s))


def main(args: list[str] | None = None) -> int:
    return run_node('sim_stage', SimStageNode, args, errors=(StageError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
