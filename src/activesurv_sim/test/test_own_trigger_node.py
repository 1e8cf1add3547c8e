"""In-process node test: a simulated camera sends the frame it rendered ahead at the instant on
its own trigger (the clock owner's mapping), without waiting for the table's state of it."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_sim.sim_camera_node import SimCameraNode

pytestmark = pytest.mark.node  # in-process rclpy nodes

# top marker xyz, side marker xyz, side normal xyz: the object at the origin, facing -y.
STATE = np.array([0.0, 0.03, 0.08, 0.0, 0.0, 0.05, 0.0, -1.0, 0.0])


def _camera(camera_id: str, own_trigger: bool) -> SimCameraNode:
    return SimCameraNode(
        parameter_overrides=[
            Parameter('camera_id', value=camera_id),
            Parameter('mount.base', value=[0.02, -0.5, 0.05]),
            Parameter('mount.yaw_offset', value=1.5708),
            Parameter('own_trigger', value=own_trigger),
        ]
    )


def _stamp(t: float) -> Any:
    from builtin_interfaces.msg import Time

    return Time(sec=int(t), nanosec=round((t - int(t)) * 1e9))


@pytest.mark.parametrize('own_trigger', [True, False])
def test_a_frame_rendered_ahead_goes_out_at_its_instant_on_the_cameras_own_clock(
    rclpy_context: Any, spin_until: Callable[..., bool], own_trigger: bool
) -> None:
    from sensor_msgs.msg import Image, JointState
    from std_msgs.msg import Float64MultiArray

    from activesurv_interfaces.msg import CaptureRequest, ObjectState

    cid = 'cam1' if own_trigger else 'cam3'
    cam = _camera(cid, own_trigger)
    peer = rclpy_context.create_node('own_trigger_test_peer')
    try:
        origin = peer.create_publisher(Float64MultiArray, topics.CLOCK_ORIGIN, qos.LATCHED)
        # Simulated time is the wall's here: simulated = (steady - wall0) * 1.
        origin.publish(Float64MultiArray(data=[time.monotonic() - time.time(), 1.0]))
        req_pub = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS)
        planned_obj = peer.create_publisher(ObjectState, topics.PLANNED_OBJECT_STATE, qos.EVENTS)
        planned_q = peer.create_publisher(JointState, topics.planned_joint_states(cid), qos.EVENTS)
        js_pub = peer.create_publisher(JointState, topics.joint_states(cid), qos.SENSOR_RELIABLE)
        frames: list[tuple[float, float]] = []  # (stamp, wall time heard)
        peer.create_subscription(
            Image,
            topics.image(cid),
            lambda m: frames.append(
                (m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, time.time())
            ),
            qos.SENSOR_RELIABLE,
        )
        assert spin_until(
            [cam, peer],
            lambda: (
                req_pub.get_subscription_count() >= 1
                and planned_q.get_subscription_count() >= 1
                and js_pub.get_subscription_count() >= 1
                and origin.get_subscription_count() >= (1 if own_trigger else 0)
            ),
            timeout=20.0,
        )
        spin_until([cam, peer], lambda: False, timeout=0.3)  # the latched origin arrives
        t_j = time.time() + 0.6
        req = CaptureRequest(demand_index=1, camera_ids=[cid], demand_instant=_stamp(t_j))
        req_pub.publish(req)
        o = ObjectState(in_workspace=True)
        o.header.stamp = _stamp(t_j)
        o.top_marker.x, o.top_marker.y, o.top_marker.z = STATE[0:3]
        o.side_marker.x, o.side_marker.y, o.side_marker.z = STATE[3:6]
        o.side_normal.x, o.side_normal.y, o.side_normal.z = STATE[6:9]
        planned_obj.publish(o)
        q = JointState(name=[f'{cid}_yaw'], position=[0.0], velocity=[0.0])
        q.header.stamp = _stamp(t_j)
        planned_q.publish(q)
        js_pub.publish(q)  # the stage's state of the instant, known ahead
        # No object state of the instant ever comes: only the camera's own trigger sends it.
        spin_until([cam, peer], lambda: bool(frames), timeout=t_j + 0.5 - time.time())
        if not own_trigger:
            assert not frames, 'sent without the states of its instant'
            return
        assert frames, 'the frame rendered ahead was not sent at its instant'
        stamp, heard = frames[0]
        assert abs(stamp - t_j) < 1e-6
        assert t_j - 0.005 <= heard < t_j + 0.25, heard - t_j
        assert cam.frames_ahead == 1
    finally:
        cam.destroy_node()
        peer.destroy_node()
