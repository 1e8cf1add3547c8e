"""The ``sim_stage`` node: a simulated camera stage with the bridge's topics and behaviour.

Subscribes: <camera_id>/stage/goal (activesurv_interfaces/StageGoal).
Publishes: <camera_id>/stage/joint_states (sensor_msgs/JointState) at ``publish_rate``,
    /diagnostics.
The axes follow the kinematics core on the node's clock (simulated time in experiments) with
the velocity and acceleration caps of the motion class (static, medium, fast). Goals outside the
soft limits, or any goal for a static camera, are refused with a logged reason.
"""

from __future__ import annotations

import math
import sys
from collections import Counter
from typing import Any, cast

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from activesurv_interfaces.msg import StageGoal
from activesurv_stages import qos, topics
from activesurv_stages.config import MOTION_CLASSES, motion_class
from activesurv_stages.conversions import goal_items, joint_state, sec_to_time
from activesurv_stages.errors import ConfigError, LimitError, StageError
from activesurv_stages.kinematics import AxisLimits, AxisSimulator


class SimStageNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('sim_stage', **kwargs)
        d = ParameterDescriptor
        self.declare_parameter('camera_id', 'cam1', d(description='topic prefix'))
        self.declare_parameter('joints', ['cam1_x', 'cam1_yaw'], d(description='joint names'))
        self.declare_parameter('kinds', ['linear', 'rotary'], d(description='linear or rotary'))
        self.declare_parameter('min', [-0.15, -1.5], d(description='soft limits (m, rad)'))
        self.declare_parameter('max', [0.15, 1.5], d(description='soft limits (m, rad)'))
        self.declare_parameter('initial', [0.0, 0.0], d(description='start positions'))
        self.declare_parameter(
            'motion_class', 'fast', d(description=f'one of {sorted(MOTION_CLASSES)}')
        )
        self.declare_parameter('publish_rate', 25.0, d(description='JointState rate (Hz)'))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')

        g = self.get_parameter
        self.camera_id = str(g('camera_id').value)
        self.joints = [str(j) for j in g('joints').value]
        kinds = [str(k) for k in g('kinds').value]
        lo, hi, init = (list(g(n).value) for n in ('min', 'max', 'initial'))
        if not (len(self.joints) == len(kinds) == len(lo) == len(hi) == len(init)):
            raise ConfigError('joints, kinds, min, max and initial need the same length')
        self.motion = motion_class(str(g('motion_class').value))
        now = self._now()
        self.axes: dict[str, AxisSimulator] = {}
        for j, k, a, b, p in zip(self.joints, kinds, lo, hi, init, strict=True):
            v, acc = self.motion.limits(k)
            # A static camera still needs limits for the model; it refuses every goal.
            limits = AxisLimits(float(a), float(b), v or 1e-9, acc or 1e-9)
            self.axes[j] = AxisSimulator(limits, float(p), now)
        self.counts: Counter[str] = Counter()
        self.last_refusal = ''

        self._pub = self.create_publisher(
            JointState, topics.joint_states(self.camera_id), qos.STATE
        )
        self._diag = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS)
        self.create_subscription(StageGoal, topics.goal(self.camera_id), self._on_goal, qos.GOAL)
        self.create_timer(1.0 / float(g('publish_rate').value), self._publish)
        self.create_timer(1.0, self._publish_diagnostics)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name == 'publish_rate' and (
                not isinstance(p.value, float)
                or not math.isfinite(p.value)
                or not 0.5 <= p.value <= 1000.0
            ):
                return SetParametersResult(
                    successful=False, reason='publish_rate must be in 0.5..1000 Hz'
                )
            if p.name == 'motion_class' and p.value not in MOTION_CLASSES:
                return SetParametersResult(
                    successful=False,
                    reason=f'motion_class must be one of {sorted(MOTION_CLASSES)}',
                )
        return SetParametersResult(successful=True)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _refuse(self, text: str) -> None:
        self.counts['refused'] += 1
        self.last_refusal = text
        self.get_logger().warning(text, throttle_duration_sec=2)

    def _on_goal(self, msg: StageGoal) -> None:
        now = self._now()
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

    def _publish(self) -> None:
        now = self._now()
        states = [self.axes[j].state(now) for j in self.joints]
        self._pub.publish(
            joint_state(
                self.joints, [s[0] for s in states], [s[1] for s in states], sec_to_time(now)
            )
        )

    def _publish_diagnostics(self) -> None:
        s = DiagnosticStatus(
            name=f'activesurv/sim_stage/{self.camera_id}', hardware_id=self.camera_id
        )
        s.level = DiagnosticStatus.WARN if self.counts['refused'] else DiagnosticStatus.OK
        s.message = f'{self.motion.name} system, {self.counts["accepted"]} goals accepted'
        s.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(self.counts.items())]
        s.values.append(KeyValue(key='last_refusal', value=self.last_refusal))
        arr = DiagnosticArray(status=[s])
        arr.header.stamp = sec_to_time(self._now())
        self._diag.publish(arr)


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, StageError)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    try:
        node = SimStageNode()
    except STARTUP_ERRORS as exc:
        print(f'sim_stage: error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
