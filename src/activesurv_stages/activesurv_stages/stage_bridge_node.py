"""The ``stage_bridge`` node: one real motion controller on a serial port.

Subscribes: <camera_id>/stage/goal (activesurv_interfaces/StageGoal); estop (std_msgs/Bool,
    reliable + transient local: the rig's e-stop, ``<namespace>/estop``; while it is true every
    goal is refused); capture_request (its camera's demand instants).
Publishes: <camera_id>/stage/joint_states (sensor_msgs/JointState, SI) at the poll rate, and
    stamped a demand instant (and ``promise_hold`` after it) as soon as the axes stand still
    before it (the dispatcher holds them still until then: :mod:`activesurv_stages.promises`),
    /diagnostics (link state,
    counters, last error, ``estop``, ``standing_still``, promises kept and broken).
Services: ~/stop (std_srvs/Trigger): stop every axis now (queued goals are dropped).
Every way out (shutdown, SIGINT, SIGTERM, SIGHUP, the orchestrator gone) stops the axes with the
protocol's own stop before the port is closed.
Parameters: config_file (controller YAML, see ``config/zaber_example.yaml``), camera_id,
    port (overrides the file), home_on_connect, reconnect_period, promise_hold.
The serial I/O runs in :class:`activesurv_stages.bridge.BridgeWorker`'s thread; the node never
blocks on the port and never dies of a serial fault.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from std_srvs.srv import Trigger

from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import sec_to_time, time_to_sec
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_interfaces.msg import CaptureRequest, StageGoal
from activesurv_stages.bridge import BridgeWorker, LinkState
from activesurv_stages.config import load_controller
from activesurv_stages.conversions import bridge_status, goal_items, joint_state, stale_goal
from activesurv_stages.drivers import make_driver
from activesurv_stages.errors import StageError
from activesurv_stages.promises import Promises

PARAMS = (
    Param('config_file', '', 'controller YAML (required)'),
    Param('camera_id', 'cam1', 'topic prefix'),
    Param('port', '', 'serial port; overrides the file'),
    Param('home_on_connect', False, 'home unreferenced axes on connect (only when asked)'),
    Param('reconnect_period', 1.0, 's between reconnects', above=0.0),
    Param(
        'promise_hold',
        0.0,
        's past a demand instant the promised state holds too (the dispatcher capture_hold)',
        minimum=0.0,
    ),
)


class StageBridgeNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('stage_bridge', **kwargs)
        declare(self, PARAMS)

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
        self.create_subscription(Bool, topics.ESTOP, self._on_estop, qos.ESTOP)
        self.create_service(Trigger, '~/stop', self._on_stop)
        self.promises = Promises(hold=float(g('promise_hold').value))
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS
        )
        self.create_timer(1.0 / cfg.poll_rate, self._publish)
        self.create_timer(1.0, self._publish_diagnostics)
        self._still_told = True  # whether standing still under the e-stop was published
        self._last_stamp = 0.0
        self._sim_time = bool(self.get_parameter('use_sim_time').value)
        self._last_state = LinkState.DISCONNECTED
        self.refusals = 0
        self.worker.start()
        self.get_logger().info(f'{cfg.protocol} controller on {cfg.port}: joints {self.joints}')

    def _on_goal(self, msg: StageGoal) -> None:
        # One message's joints are queued together: one move on a multi-axis controller.
        stale = stale_goal(msg, self._now())
        for reason in [stale] if stale else self.worker.submit_goals(list(goal_items(msg))):
            self.refusals += 1
            self.get_logger().warning(f'goal refused, nothing sent: {reason}')

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_request(self, msg: CaptureRequest) -> None:
        if self.camera_id in msg.camera_ids:
            self.promises.request(time_to_sec(msg.demand_instant), self._now())

    def _on_estop(self, msg: Bool) -> None:
        raised = bool(msg.data)
        if raised == self.worker.estop:
            return
        self.worker.set_estop(raised)
        if raised:
            self.get_logger().error('e-stop raised: axes stopped, every goal refused')
            self._still_told = False
        else:
            self.get_logger().warning('e-stop released: goals accepted again')
        self._publish_diagnostics()

    def _on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.worker.stop_all()
        self.get_logger().warning('stop requested (~/stop): axes stopped, queued goals dropped')
        response.success = True
        response.message = f'stop sent to {", ".join(self.joints)}'
        return response

    def _publish(self) -> None:
        snap = self.worker.snapshot()
        if not self._still_told and self.worker.standing_still():
            self._still_told = True
            self._publish_diagnostics()  # what activesurv stop waits for
        if snap.state is not self._last_state:
            text = f'controller {self._last_state.value} -> {snap.state.value}' + (
                f' ({snap.last_error})' if snap.last_error else ''
            )
            if snap.state is LinkState.READY:
                self.get_logger().info(text)
            else:
                self.get_logger().warning(text)
            self._last_state = snap.state
        names = [j for j in self.joints if j in snap.positions]
        for t, q in self.promises.due(self._now(), self.worker.settled(), snap.positions):
            self._pub.publish(
                joint_state(names, [q[j] for j in names], [0.0] * len(names), sec_to_time(t))
            )
        if snap.stamp == self._last_stamp or not snap.positions:
            return  # no new poll: publish only what the controller said
        self._last_stamp = snap.stamp
        # Stamped when the controller reported (not when this timer fired, up to a poll period
        # later): what the imager and the truth interpolate at a frame's instant.
        stamp = self.get_clock().now().to_msg() if self._sim_time else sec_to_time(snap.wall)
        for why in self.promises.check(time_to_sec(stamp), snap.positions):
            self.get_logger().warning(why)
        self._pub.publish(
            joint_state(
                names,
                [snap.positions[j] for j in names],
                [snap.velocities.get(j, 0.0) for j in names],
                stamp,
            )
        )

    def _publish_diagnostics(self) -> None:
        extra = {
            'refused_goals': self.refusals,
            'estop': str(self.worker.estop).lower(),
            'standing_still': str(self.worker.standing_still()).lower(),
            'namespace': self.get_namespace(),
            'promises_kept': self.promises.kept,
            'promises_broken': self.promises.broken,
        }
        s = bridge_status(
            self.camera_id, self.cfg, self.worker.snapshot(), self.worker.estop, extra
        )
        arr = DiagnosticArray(status=[s])
        arr.header.stamp = self.get_clock().now().to_msg()
        self._diag.publish(arr)

    def destroy_node(self) -> None:
        self.worker.shutdown()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node('stage_bridge', StageBridgeNode, args, errors=(StageError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
