"""The ``frames`` node: the rig's frame tree on /tf and /tf_static (like robot_state_publisher).

Publishes: /tf_static (tf2_msgs/TFMessage, latched): ``world -> <cam>_base``,
    ``<cam>_platform -> <cam>_optical_frame`` for every camera of the set-up, and
    ``world -> overhead_optical_frame``; /tf (tf2_msgs/TFMessage): ``<cam>_base ->
    <cam>_platform`` from each stage state, at its stamp, and ``world -> object`` from
    each tracked fix (:mod:`activesurv_common.frames`): every transform, gathered into one
    message every ``publish_period`` (each keeps its own stamp; 0: one message per state, as
    robot_state_publisher does). One message instead of five wakes each /tf subscriber once:
    on a host where waking a process costs more than the message, that is most of /tf's CPU.
Subscribes: <cam>/stage/joint_states (sensor_msgs/JointState), overhead/track
    (geometry_msgs/PointStamped, world).
Parameters: see ``config/frames.yaml``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from activesurv_common import frames
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.ros import local_topics, qos, topics
from activesurv_common.ros.conversions import joint_vector, transform_stamped
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_dispatch.sensors import load_setup
from activesurv_stages.config import MOTION_CLASSES


def _pose_problem(v: Any) -> str | None:
    if len(v) not in (0, 7):
        return 'overhead_pose: x, y, z, qx, qy, qz, qw (or empty: no overhead camera)'
    return None


PARAMS = (
    Param('setup_file', '', 'set-up YAML; empty: the paper set-up'),
    Param('motion_class', 'fast', 'set-up motion class', choices=tuple(sorted(MOTION_CLASSES))),
    Param(
        'overhead_pose', Parameter.Type.DOUBLE_ARRAY, 'overhead camera pose', check=_pose_problem
    ),
    Param(
        'publish_period',
        0.1,
        's between /tf messages (each holds every transform since the last); 0: one per state',
        minimum=0.0,
        maximum=10.0,
    ),
)


class FramesNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('frames', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter_or(p.name, Parameter(p.name)).value for p in PARAMS}
        self.setup = load_setup(str(v['setup_file']) or None, str(v['motion_class']))
        pose = [float(x) for x in (v['overhead_pose'] or [])]
        overhead = Transform.from_rt(matrix_from_quaternion(pose[3:]), pose[:3]) if pose else None
        self._tf = self.create_publisher(TFMessage, topics.TF, qos.TF)
        static = self.create_publisher(TFMessage, topics.TF_STATIC, qos.TF_STATIC)
        stamp = self.get_clock().now().to_msg()
        edges = frames.static_edges((s.mount for s in self.setup.sensors), overhead)
        static.publish(TFMessage(transforms=[transform_stamped(*e, stamp) for e in edges]))
        self.bad_states = 0
        self._pending: list[Any] = []  # TransformStamped not yet on /tf
        period = float(v['publish_period'])
        self._batched = period > 0.0
        if self._batched:
            self.create_timer(period, self._flush)
        for s in self.setup.sensors:
            self.create_subscription(
                JointState,
                topics.joint_states(s.camera_id),
                self._on_joints(s.camera_id),
                qos.SENSOR,
            )
        track, cb = topics.OVERHEAD_TRACK, self._on_track  # the predictor's, in process
        local_topics.subscription(self, PointStamped, track, cb, qos.SENSOR, only_local=True)
        self.get_logger().info(f'{len(edges)} static frames; {len(self.setup.sensors)} stages')

    def _on_joints(self, camera_id: str) -> Callable[[JointState], None]:
        mount = self.setup.sensor(camera_id).mount

        def callback(msg: JointState) -> None:
            q = joint_vector(msg, mount.joint_names)
            try:
                if q is None:
                    raise CalibrationError('joint names do not match')
                edge = frames.joint_edge(mount, q)
            except CalibrationError as exc:
                self.bad_states += 1
                self.get_logger().warning(f'{camera_id}: bad stage state: {exc}', once=True)
                return
            self._send(transform_stamped(*edge, msg.header.stamp))

        return callback

    def _on_track(self, msg: PointStamped) -> None:
        edge = frames.object_edge((msg.point.x, msg.point.y, msg.point.z))
        self._send(transform_stamped(*edge, msg.header.stamp))

    def _send(self, transform: Any) -> None:
        self._pending.append(transform)
        if not self._batched:
            self._flush()

    def _flush(self) -> None:
        if self._pending:
            self._tf.publish(TFMessage(transforms=self._pending))
            self._pending = []


def main(args: list[str] | None = None) -> int:
    return run_node('frames', FramesNode, args, errors=(CalibrationError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
