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
        (visualization_msgs/MarkerArray, every ``marker_period``), /diagnostics.
Parameters: see ``config/dispatcher.yaml``. The decisions are
:class:`activesurv_dispatch.session.Dispatcher`'s; this node converts and publishes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from activesurv_common.pacing import ViewThrottle
from activesurv_common.ros import diagnostics, local_topics, qos, topics
from activesurv_common.ros.conversions import joint_vector, sec_to_time, time_to_sec
from activesurv_common.ros.fine_clock import FineClock
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.conversions import (
    capture_to_request,
    command_to_goal,
    horizon_to_demands,
    plan_markers,
    plan_to_msg,
    plan_view_key,
    stage_faults,
)
from activesurv_dispatch.errors import DispatchError
from activesurv_dispatch.sensors import load_setup
from activesurv_dispatch.session import Dispatcher, DispatcherConfig, Outputs
from activesurv_interfaces.msg import CaptureRequest, DemandHorizon, DispatchPlan, StageGoal
from activesurv_stages.config import MOTION_CLASSES

PARAMS = (
    Param('setup_file', '', 'set-up YAML; empty: the paper set-up'),
    Param('motion_class', 'fast', 'camera speeds', choices=tuple(sorted(MOTION_CLASSES))),
    Param('sensor_model_file', '', 'sensor model YAML; empty: the packaged model'),
    Param('k', 3, 'fusion subset size', minimum=1),
    Param('rho', 1.0, 'replanning box in prediction sigmas', above=0.0),
    Param('capture_lead', 0.3, 's before a demand instant to request capture', above=0.0),
    Param('settle_time', 0.1, 's to be still before capture', above=0.0),
    Param('camera_timeout', 0.5, 's without stage state or heartbeat: drop', above=0.0),
    Param(
        'capture_grace', 0.1, 's a capture request may wait for a fresh prediction', minimum=0.0
    ),
    Param('capture_hold', 0.0, 's past an instant its cameras stay still', minimum=0.0),
    Param('replan_quiet', 0.05, 's past an instant before planning its cameras', minimum=0.0),
    Param('frame_id', 'world', 'frame of plans and markers'),
    Param('marker_period', 0.2, 's between markers (at once on new roles); 0: all', minimum=0.0),
)


class DispatcherNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('dispatcher', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.setup = load_setup(str(v['setup_file']) or None, str(v['motion_class']))
        config = DispatcherConfig.from_parameters(v)
        model = SensorModel.load(str(v['sensor_model_file']) or None)
        self.session, self._fine = (
            Dispatcher(self.setup, model, config),
            FineClock(self.get_clock(), self),
        )
        self.frame_id = str(v['frame_id'])
        self._camera_changes, self._markers = (0, 0), ViewThrottle(float(v['marker_period']))
        self._goal_pubs = {
            s.camera_id: self.create_publisher(StageGoal, topics.goal(s.camera_id), qos.GOAL)
            for s in self.setup.sensors
        }
        self._capture_pub = self.create_publisher(
            CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS_LATCHED
        )
        self._plan_pub = self.create_publisher(DispatchPlan, topics.DISPATCH_PLAN, qos.LATCHED)
        self._marker_pub = self.create_publisher(MarkerArray, topics.DISPATCH_MARKERS, qos.LATCHED)
        self._diag_pub = self.create_publisher(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        horizon, cb = topics.DEMAND_HORIZON, self._on_horizon  # the predictor's, in process
        local_topics.subscription(self, DemandHorizon, horizon, cb, qos.LATCHED, only_local=True)
        for s in self.setup.sensors:
            cid = s.camera_id
            self.create_subscription(
                JointState, topics.joint_states(cid), self._joint_callback(cid), qos.SENSOR
            )
            self.create_subscription(
                Header, topics.heartbeat(cid), self._beat_callback(cid), qos.SENSOR
            )
        # Stage bridges' diagnostics: a stall, a lost controller or the e-stop takes the camera
        # out of dispatching at once.
        self.create_subscription(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, self._on_diagnostics, qos.DIAGNOSTICS
        )
        self.create_timer(0.05, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)
        self.get_logger().info(
            f'{len(self.setup.sensors)} cameras, {self.setup.motion.name} system, k={config.k}'
        )

    def _now(self) -> float:  # when a message came, between /clock ticks too
        return self._fine.now()

    def _joint_callback(self, camera_id: str) -> Callable[[JointState], None]:
        names = self.setup.sensor(camera_id).joint_names

        def callback(msg: JointState) -> None:
            q = joint_vector(msg, names)
            if q is None:
                self.session.counts['bad_joint_states'] += 1
                return
            self._publish(self.session.on_joints(camera_id, q, self._now()))

        return callback

    def _beat_callback(self, camera_id: str) -> Callable[[Header], None]:
        def callback(msg: Header) -> None:
            self.session.on_beat(camera_id, self._now())

        return callback

    def _on_horizon(self, msg: DemandHorizon) -> None:
        demands = horizon_to_demands(msg)
        dropped = len(msg.demands) - len(demands)
        # Decided at its frame, as lockstep does (the goals then start there), and then the
        # rest of a step; on a clock past it (a rig's, or a late horizon), at that clock.
        stamp = time_to_sec(msg.header.stamp)
        now = max(stamp, self.get_clock().now().nanoseconds * 1e-9)
        out = self.session.set_horizon(demands, now, dropped, msg.manoeuvre_count, stamp)
        out.merge(self.session.tick(now))
        self._publish(out, now)

    def _on_diagnostics(self, msg: diagnostics.DiagnosticArray) -> None:
        for cid, fault in stage_faults(msg, self.get_namespace()).items():
            self._publish(self.session.on_stage_fault(cid, fault, self._now()))

    def _on_tick(self) -> None:  # at the tick's own time, as a horizon at its frame's
        now = self.get_clock().now().nanoseconds * 1e-9
        self._publish(self.session.tick(now), now)

    def _publish(self, out: Outputs, at: float | None = None) -> None:
        now = self._now() if at is None else at
        for cmd in out.goals:
            self._goal_pubs[cmd.camera_id].publish(command_to_goal(cmd, now))
        for capture in [*out.captures, *out.missed]:
            self._capture_pub.publish(capture_to_request(capture, now, self.frame_id))
        if out.plan is not None:
            s = self.session
            self._plan_pub.publish(
                plan_to_msg(out.plan, self.setup, s.planner.replans, self.frame_id)
            )
            if self._markers.due(out.plan.stamp, plan_view_key(out.plan)):
                markers = plan_markers(out.plan, self.setup, s.joints, s.horizon, self.frame_id)
                self._marker_pub.publish(markers)
        changes = (self.session.counts['cameras_lost'], self.session.counts['cameras_back'])
        if changes != self._camera_changes:
            self._camera_changes = changes
            self._publish_diagnostics()  # a camera went down or came back: say so at once
        log = self.get_logger()
        for level, text in out.events:
            # rclpy ties a severity to each call site: one call per severity.
            if level == 'warning':
                log.warning(text)
            else:
                log.info(text)

    def _publish_diagnostics(self) -> None:
        values = self.session.status()
        down = values['cameras_down']
        s = diagnostics.status(
            'activesurv/dispatcher',
            'dispatcher',
            f'serving demand {values["serving"]}' + (f'; cameras down: {down}' if down else ''),
            values,
            diagnostics.WARN if down else diagnostics.OK,
        )
        # Stamped between /clock ticks too: a camera dropped or re-admitted says when.
        self._diag_pub.publish(diagnostics.array(sec_to_time(self._now()), s))


def main(args: list[str] | None = None) -> int:
    return run_node('dispatcher', DispatcherNode, args, errors=(DispatchError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
