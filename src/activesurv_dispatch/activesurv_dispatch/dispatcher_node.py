"""The ``dispatcher`` node: assigns and positions the cameras for each demand instant.

Subscribes:
    demand_horizon (activesurv_interfaces/DemandHorizon, latched): the rolling horizon.
    <cam>/stage/joint_states (sensor_msgs/JointState): each camera's stage state.
    <cam>/imager/heartbeat (std_msgs/Header): each imager's liveness beat.
Publishes:
    <cam>/stage/goal (activesurv_interfaces/StageGoal, latched): desired stage positions.
    capture_request (activesurv_interfaces/CaptureRequest): ``capture_lead`` s before each
        demand instant, to the cameras assigned to it.
    dispatch_plan (activesurv_interfaces/DispatchPlan, latched), dispatch_markers
        (visualization_msgs/MarkerArray), /diagnostics.
Every horizon update triggers planning (assignment, preassignment, replanning); a timer issues
capture requests and retires serviced demands. A camera whose stage state is older than
``camera_timeout`` s, or whose imager has beaten before and then fell silent for as long, is
taken out of dispatching (its frozen assignments are reassigned at once) and put back when both
are heard again.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter
from collections.abc import Callable
from typing import Any, cast

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from activesurv_dispatch import qos, topics
from activesurv_dispatch.conversions import (
    capture_to_request,
    command_to_goal,
    horizon_to_demands,
    plan_markers,
    plan_to_msg,
)
from activesurv_dispatch.errors import DispatchError
from activesurv_dispatch.motion import CaptureScheduler, MotionController
from activesurv_dispatch.planner import Demand, DispatchPlanner, Plan
from activesurv_dispatch.sensors import load_setup
from activesurv_imaging.sensor_model import SensorModel
from activesurv_interfaces.msg import CaptureRequest, DemandHorizon, DispatchPlan, StageGoal
from activesurv_stages.config import MOTION_CLASSES

POSITIVE = ('rho', 'capture_lead', 'settle_time', 'camera_timeout')


class DispatcherNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('dispatcher', **kwargs)
        d = ParameterDescriptor
        self.declare_parameter('setup_file', '', d(description='set-up YAML; empty: paper'))
        self.declare_parameter(
            'motion_class', 'fast', d(description=f'one of {sorted(MOTION_CLASSES)}')
        )
        self.declare_parameter('sensor_model_file', '', d(description='empty: packaged model'))
        self.declare_parameter('k', 3, d(description='fusion subset size'))
        self.declare_parameter('rho', 1.0, d(description='replanning box in prediction sigmas'))
        self.declare_parameter(
            'capture_lead', 0.3, d(description='s before a demand instant to request capture')
        )
        self.declare_parameter('settle_time', 0.1, d(description='s to be still before capture'))
        self.declare_parameter(
            'camera_timeout',
            0.5,
            d(description='s without stage state or imager heartbeat before a camera is dropped'),
        )
        self.declare_parameter('frame_id', 'world', d(description='frame of plans and markers'))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')

        g = self.get_parameter
        setup_file = str(g('setup_file').value)
        self.setup = load_setup(setup_file or None, str(g('motion_class').value))
        self.model = SensorModel.load(str(g('sensor_model_file').value) or None)
        self.planner = DispatchPlanner(
            self.setup,
            self.model,
            int(g('k').value),
            float(g('rho').value),
            float(g('settle_time').value),
        )
        self.motion = MotionController(self.setup)
        self.scheduler = CaptureScheduler(float(g('capture_lead').value))
        self.frame_id = str(g('frame_id').value)
        self.joints: dict[str, np.ndarray] = {}
        self.joint_stamp: dict[str, float] = {}
        self.beat_stamp: dict[str, float] = {}
        self.down: dict[str, str] = {}  # camera -> why it is out of dispatching
        self.demands: dict[int, Demand] = {}
        self.horizon: list[Demand] = []
        self.plan: Plan | None = None
        self.plan_ms: list[float] = []
        self.counts: Counter[str] = Counter()

        self._goal_pubs = {
            s.camera_id: self.create_publisher(StageGoal, topics.goal(s.camera_id), qos.LATCHED)
            for s in self.setup.sensors
        }
        self._capture_pub = self.create_publisher(
            CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS_LATCHED
        )
        self._plan_pub = self.create_publisher(DispatchPlan, topics.DISPATCH_PLAN, qos.LATCHED)
        self._marker_pub = self.create_publisher(MarkerArray, topics.MARKERS, qos.LATCHED)
        self._diag_pub = self.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_subscription(
            DemandHorizon, topics.DEMAND_HORIZON, self._on_horizon, qos.LATCHED
        )
        for s in self.setup.sensors:
            self.create_subscription(
                JointState,
                topics.joint_states(s.camera_id),
                self._joint_callback(s.camera_id),
                qos.SENSOR,
            )
            self.create_subscription(
                Header, topics.heartbeat(s.camera_id), self._beat_callback(s.camera_id), qos.SENSOR
            )
        self.create_timer(0.05, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)
        self.get_logger().info(
            f'{len(self.setup.sensors)} cameras, {self.setup.motion.name} system, '
            f'k={self.planner.k}'
        )

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name in POSITIVE and (
                not isinstance(p.value, float) or not math.isfinite(p.value) or p.value <= 0.0
            ):
                return SetParametersResult(
                    successful=False, reason=f'{p.name} must be a finite float > 0'
                )
            if p.name == 'k' and (not isinstance(p.value, int) or p.value < 1):
                return SetParametersResult(successful=False, reason='k must be an integer >= 1')
            if p.name == 'motion_class' and p.value not in MOTION_CLASSES:
                return SetParametersResult(
                    successful=False,
                    reason=f'motion_class must be one of {sorted(MOTION_CLASSES)}',
                )
        return SetParametersResult(successful=True)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # -- inputs ------------------------------------------------------------------------------
    def _joint_callback(self, camera_id: str) -> Callable[[JointState], None]:
        def callback(msg: JointState) -> None:
            self._on_joints(camera_id, msg)

        return callback

    def _beat_callback(self, camera_id: str) -> Callable[[Header], None]:
        def callback(msg: Header) -> None:
            self.beat_stamp[camera_id] = self._now()

        return callback

    def _on_joints(self, camera_id: str, msg: JointState) -> None:
        names = self.setup.sensor(camera_id).joint_names
        table = dict(zip(msg.name, msg.position, strict=False))
        q = np.array([table.get(n, math.nan) for n in names], dtype=np.float64)
        if not np.all(np.isfinite(q)):
            self.counts['bad_joint_states'] += 1
            return
        self.joints[camera_id] = q
        self.joint_stamp[camera_id] = self._now()
        if camera_id in self.down:
            self._check_alive(self._now())

    def _on_horizon(self, msg: DemandHorizon) -> None:
        demands = horizon_to_demands(msg)
        if len(demands) != len(msg.demands):
            self.counts['bad_demands'] += len(msg.demands) - len(demands)
        for dm in demands:
            self.demands[dm.index] = dm
        self.horizon = demands
        self._replan()

    # -- work --------------------------------------------------------------------------------
    def _replan(self) -> None:
        if not self.joints:
            return
        t0 = time.perf_counter()
        now = self._now()
        plan = self.planner.plan(now, self.horizon, self.joints)
        self.plan_ms.append(1e3 * (time.perf_counter() - t0))
        self.plan_ms = self.plan_ms[-200:]
        self.plan = plan
        if plan.replanned:
            self.get_logger().info(f'replanned demand {plan.first_index}: the prediction moved')
        for cmd in self.motion.commands(plan, self.demands):
            self._goal_pubs[cmd.camera_id].publish(command_to_goal(cmd, now))
            self.counts['goals'] += 1
        self._plan_pub.publish(plan_to_msg(plan, self.setup, self.planner.replans, self.frame_id))
        self._marker_pub.publish(
            plan_markers(plan, self.setup, self.joints, self.horizon, self.frame_id)
        )

    def _check_alive(self, now: float) -> None:
        """Take cameras whose stage or imager fell silent out of dispatching; re-admit them."""
        timeout = float(self.get_parameter('camera_timeout').value)
        changed = False
        for cid, stamp in self.joint_stamp.items():
            why = ''
            if now - stamp > timeout:
                why = f'no stage state for {timeout:g} s'
            elif cid in self.beat_stamp and now - self.beat_stamp[cid] > timeout:
                why = f'no imager heartbeat for {timeout:g} s'
            if why and cid not in self.down:
                self.down[cid] = why
                self.planner.exclude(cid)
                self.counts['cameras_lost'] += 1
                self.get_logger().warning(f'{cid}: {why}; dispatching without it (t={now:.2f} s)')
                changed = True
            elif not why and cid in self.down:
                del self.down[cid]
                self.planner.exclude(cid, dead=False)
                self.motion.forget(cid)
                self.counts['cameras_back'] += 1
                self.get_logger().info(f'{cid} is back: dispatching it again (t={now:.2f} s)')
                changed = True
        if changed:
            self._replan()

    def _on_tick(self) -> None:
        now = self._now()
        self._check_alive(now)
        if self.plan is not None:
            capture = self.scheduler.due(now, self.plan, self.demands)
            if capture is not None:
                self._capture_pub.publish(capture_to_request(capture, now, self.frame_id))
                self.planner.close(capture.demand.index)
                self.motion.holding.update(capture.cameras)
                self.counts['captures'] += 1
                self.get_logger().info(
                    f'capture demand {capture.demand.index} at '
                    f'{capture.demand.time:.2f} s with {list(capture.cameras)}'
                )
        for missed in self.scheduler.missed(now, self.demands):
            self._capture_pub.publish(capture_to_request(missed, now, self.frame_id))
            self.planner.serviced(missed.demand.index)
            self.counts['missed_demands'] += 1
            self.get_logger().warning(
                f'demand {missed.demand.index} passed with no camera '
                'assigned; reported as a failure'
            )
        for done in self.scheduler.newly_serviced(now):
            self.planner.serviced(done.demand.index)
            self.motion.holding.difference_update(done.cameras)
            self._replan()

    def _publish_diagnostics(self) -> None:
        s = DiagnosticStatus(name='activesurv/dispatcher', hardware_id='dispatcher')
        excluded = sorted(self.planner.excluded)
        s.level = DiagnosticStatus.WARN if excluded else DiagnosticStatus.OK
        first = self.plan.first_index if self.plan else -1
        s.message = f'serving demand {first}' + (f'; cameras down: {excluded}' if excluded else '')
        ms = np.array(self.plan_ms) if self.plan_ms else np.array([math.nan])
        s.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(self.counts.items())]
        s.values += [
            KeyValue(key='plan_ms_median', value=f'{float(np.median(ms)):.2f}'),
            KeyValue(key='replans', value=str(self.planner.replans)),
            KeyValue(key='cameras_with_state', value=str(sorted(self.joints))),
            KeyValue(key='cameras_down', value=str(excluded)),
            KeyValue(key='why_down', value=str(self.down)),
        ]
        arr = DiagnosticArray(status=[s])
        arr.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(arr)


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, DispatchError)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    try:
        node = DispatcherNode()
    except STARTUP_ERRORS as exc:
        print(f'dispatcher: error: {exc}', file=sys.stderr)
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
