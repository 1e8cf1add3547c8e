"""The ``stage_bridge`` node: one real motion controller on a serial port.

Subscribes: <camera_id>/stage/goal (activesurv_interfaces/StageGoal).
Publishes: <camera_id>/stage/joint_states (sensor_msgs/JointState, SI) at the poll rate,
    /diagnostics (link state, counters, last error).
Parameters: config_file (controller YAML, see ``config/zaber_example.yaml``), camera_id,
    port (overrides the file), home_on_connect, reconnect_period.
The serial I/O runs in :class:`activesurv_stages.bridge.BridgeWorker`'s thread; the node never
blocks on the port and never dies of a serial fault.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
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
from activesurv_stages.bridge import BridgeWorker, LinkState
from activesurv_stages.config import load_controller
from activesurv_stages.conversions import goal_items, joint_state
from activesurv_stages.drivers import make_driver
from activesurv_stages.errors import StageError


class StageBridgeNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('stage_bridge', **kwargs)
        d = ParameterDescriptor
        self.declare_parameter('config_file', '', d(description='controller YAML'))
        self.declare_parameter('camera_id', 'cam1', d(description='topic prefix'))
        self.declare_parameter('port', '', d(description='serial port; overrides the file'))
        self.declare_parameter('home_on_connect', True, d(description='home unreferenced axes'))
        self.declare_parameter('reconnect_period', 1.0, d(description='s between reconnects'))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')

        g = self.get_parameter
        path = str(g('config_file').value)
        if not path:
            raise StageError('stage_bridge needs the config_file parameter (controller YAML)')
        cfg = load_controller(path)
        port = str(g('port').value) or cfg.port
        cfg = replace(cfg, port=port)
        self.cfg = cfg
        self.camera_id = str(g('camera_id').value)
        self.joints = [a.joint for a in cfg.axes]
        self.worker = BridgeWorker(
            lambda: make_driver(cfg.protocol, cfg.port, cfg.baud),
            list(cfg.axes),
            cfg.poll_rate,
            float(g('reconnect_period').value),
            bool(g('home_on_connect').value),
        )
        self._pub = self.create_publisher(
            JointState, topics.joint_states(self.camera_id), qos.STATE
        )
        self._diag = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS)
        self.create_subscription(StageGoal, topics.goal(self.camera_id), self._on_goal, qos.GOAL)
        self.create_timer(1.0 / cfg.poll_rate, self._publish)
        self.create_timer(1.0, self._publish_diagnostics)
        self._last_stamp = 0.0
        self._last_state = LinkState.DISCONNECTED
        self.refusals = 0
        self.worker.start()
        self.get_logger().info(f'{cfg.protocol} controller on {cfg.port}: joints {self.joints}')

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name == 'reconnect_period' and (
                not isinstance(p.value, float) or not math.isfinite(p.value) or p.value <= 0
            ):
                return SetParametersResult(
                    successful=False, reason='reconnect_period must be a float > 0'
                )
        return SetParametersResult(successful=True)

    def _on_goal(self, msg: StageGoal) -> None:
        for joint, position, velocity in goal_items(msg):
            try:
                self.worker.submit_goal(joint, position, velocity)
            except StageError as exc:
                self.refusals += 1
                self.get_logger().warning(f'goal refused, nothing sent: {exc}')

    def _publish(self) -> None:
        snap = self.worker.snapshot()
        if snap.state is not self._last_state:
            text = f'controller {self._last_state.value} -> {snap.state.value}' + (
                f' ({snap.last_error})' if snap.last_error else ''
            )
            if snap.state is LinkState.READY:
                self.get_logger().info(text)
            else:
                self.get_logger().warning(text)
            self._last_state = snap.state
        if snap.stamp == self._last_stamp or not snap.positions:
            return  # no new poll: publish only what the controller said
        self._last_stamp = snap.stamp
        names = [j for j in self.joints if j in snap.positions]
        self._pub.publish(
            joint_state(
                names,
                [snap.positions[j] for j in names],
                [snap.velocities.get(j, 0.0) for j in names],
                self.get_clock().now().to_msg(),
            )
        )

    def _publish_diagnostics(self) -> None:
        snap = self.worker.snapshot()
        s = DiagnosticStatus(
            name=f'activesurv/stage_bridge/{self.camera_id}',
            hardware_id=f'{self.cfg.protocol}:{self.cfg.port}',
        )
        s.level = {
            LinkState.READY: DiagnosticStatus.OK,
            LinkState.HOMING: DiagnosticStatus.WARN,
            LinkState.DISCONNECTED: DiagnosticStatus.ERROR,
        }[snap.state]
        if any(v == 'fault' for v in snap.statuses.values()):
            s.level = DiagnosticStatus.ERROR
        s.message = snap.state.value + (f': {snap.last_error}' if snap.last_error else '')
        s.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(snap.counters.items())]
        s.values += [
            KeyValue(key=f'status/{j}', value=v) for j, v in sorted(snap.statuses.items())
        ]
        s.values.append(KeyValue(key='refused_goals', value=str(self.refusals)))
        arr = DiagnosticArray(status=[s])
        arr.header.stamp = self.get_clock().now().to_msg()
        self._diag.publish(arr)

    def destroy_node(self) -> None:
        self.worker.shutdown()
        super().destroy_node()


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, StageError)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    try:
        node = StageBridgeNode()
    except STARTUP_ERRORS as exc:
        print(f'stage_bridge: error: {exc}', file=sys.stderr)
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
