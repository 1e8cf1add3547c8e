"""The frame tree: its chain equals the camera poses the system computes, and the frames node
publishes it on /tf_static (latched) and /tf (from stage states and the track) over DDS."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from activesurv_common import frames
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import sec_to_time
from activesurv_dispatch.sensors import load_setup

pytestmark = pytest.mark.node  # in-process rclpy nodes

OVERHEAD = [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0]


def _edges_from(msgs: list[Any]) -> list[frames.Edge]:
    out = []
    for m in msgs:
        for t in m.transforms:
            r, p = t.transform.rotation, t.transform.translation
            T = Transform.from_rt(matrix_from_quaternion([r.x, r.y, r.z, r.w]), [p.x, p.y, p.z])
            out.append(frames.Edge(t.header.frame_id, t.child_frame_id, T))
    return out


@pytest.mark.parametrize('seed', range(5))
def test_the_chain_is_the_camera_pose(seed: int) -> None:
    rng = np.random.default_rng(seed)
    setup = load_setup()
    for s in setup.sensors:
        q = rng.uniform(-0.5, 0.5, len(s.joint_names))
        edges = frames.static_edges([s.mount]) + [frames.joint_edge(s.mount, q)]
        T = frames.chain(edges, frames.optical_frame(s.camera_id))
        expected = s.mount.pose_from_joints(q)
        assert np.allclose(T.R, expected.R, atol=1e-12)
        assert np.allclose(T.t, expected.t, atol=1e-12)
    with pytest.raises(CalibrationError):
        frames.joint_edge(setup.sensors[0].mount, [np.nan] * len(setup.sensors[0].joint_names))


def test_frames_node_publishes_the_tree(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from tf2_msgs.msg import TFMessage

    from activesurv_liveview.frames_node import FramesNode

    node = FramesNode(parameter_overrides=[Parameter('overhead_pose', value=OVERHEAD)])
    peer = rclpy_context.create_node('frames_test_peer')
    static: list[Any] = []
    dynamic: list[Any] = []
    # Subscribed after the static tree went out: transient local brings it all the same.
    peer.create_subscription(TFMessage, topics.TF_STATIC, static.append, qos.TF_STATIC)
    peer.create_subscription(TFMessage, topics.TF, dynamic.append, qos.TF)
    setup = node.setup
    joint_pubs = {
        s.camera_id: peer.create_publisher(JointState, topics.joint_states(s.camera_id), qos.STATE)
        for s in setup.sensors
    }
    track = peer.create_publisher(PointStamped, topics.OVERHEAD_TRACK, qos.SENSOR)
    q = {s.camera_id: np.full(len(s.joint_names), 0.1) for s in setup.sensors}

    def step() -> bool:
        for s in setup.sensors:
            msg = JointState(name=list(s.joint_names), position=[float(v) for v in q[s.camera_id]])
            msg.header.stamp = sec_to_time(3.25)
            joint_pubs[s.camera_id].publish(msg)
        p = PointStamped()
        p.header.stamp = sec_to_time(3.25)
        p.point.x, p.point.y, p.point.z = 0.2, 0.1, 0.08
        track.publish(p)
        children = {t.child_frame_id for m in dynamic for t in m.transforms}
        return bool(static) and children >= {'object'} | {f'{c}_platform' for c in q}

    try:
        assert spin_until([node, peer], step, timeout=20.0)
        edges = _edges_from(static) + _edges_from(dynamic)
        assert all(
            t.header.stamp.sec == 3 and t.header.stamp.nanosec == 250_000_000
            for m in dynamic
            for t in m.transforms
        )
        for s in setup.sensors:
            T = frames.chain(edges, f'{s.camera_id}_optical_frame')
            expected = s.mount.pose_from_joints(q[s.camera_id])
            assert np.allclose(T.t, expected.t, atol=1e-9)
            assert np.allclose(T.R, expected.R, atol=1e-9)
        assert np.allclose(frames.chain(edges, 'overhead_optical_frame').t, OVERHEAD[:3])
        assert np.allclose(frames.chain(edges, 'object').t, [0.2, 0.1, 0.08])
    finally:
        for n in (node, peer):
            n.destroy_node()
