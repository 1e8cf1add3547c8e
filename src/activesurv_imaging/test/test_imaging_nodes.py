"""In-process node test: sim_camera + imager; a CaptureRequest in, a MarkerObservation out."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_imaging.imager_node import ImagerNode
from activesurv_sim.sim_camera_node import SimCameraNode

pytestmark = pytest.mark.node  # in-process rclpy nodes

MARKER = np.array([0.2, 0.0, 0.05])
BEARING = math.radians(30.0)
BASE = MARKER + 0.55 * np.array([math.sin(BEARING), -math.cos(BEARING), 0.0])
YAW = math.atan2(MARKER[1] - BASE[1], MARKER[0] - BASE[0])


def _mount(camera_id: str) -> list[Parameter]:
    return [
        Parameter('camera_id', value=camera_id),
        Parameter('mount.base', value=BASE.tolist()),
        Parameter('mount.yaw_offset', value=0.0),
    ]


@pytest.fixture
def nodes(rclpy_context: Any) -> Any:
    cam = SimCameraNode(parameter_overrides=[*_mount('cam2'), Parameter('seed', value=3)])
    imager = ImagerNode(
        parameter_overrides=[*_mount('cam2'), Parameter('frame_timeout', value=1.5)]
    )
    # An imager whose camera never delivers a frame.
    blind = ImagerNode(
        parameter_overrides=[*_mount('cam9'), Parameter('frame_timeout', value=0.5)]
    )
    peer = rclpy_context.create_node('imaging_test_peer')
    yield cam, imager, blind, peer
    for n in (cam, imager, blind, peer):
        n.destroy_node()


def test_capture_request_gives_marker_observation(
    nodes: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import JointState

    from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, ObjectState

    cam, imager, blind, peer = nodes
    obj_pub = peer.create_publisher(ObjectState, topics.OBJECT_STATE, qos.SENSOR_RELIABLE)
    js_pub = peer.create_publisher(JointState, topics.joint_states('cam2'), qos.SENSOR_RELIABLE)
    js9_pub = peer.create_publisher(JointState, topics.joint_states('cam9'), qos.SENSOR_RELIABLE)
    req_pub = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS)
    got: list[MarkerObservation] = []
    peer.create_subscription(MarkerObservation, topics.MARKER_OBSERVATIONS, got.append, qos.EVENTS)
    state = {'marker': MARKER.copy()}

    def publish_states() -> None:
        now = peer.get_clock().now().to_msg()
        o = ObjectState(in_workspace=True)
        o.header.stamp = now
        m = state['marker']
        o.side_marker.x, o.side_marker.y, o.side_marker.z = m
        o.side_normal.y = -1.0
        o.top_marker.x, o.top_marker.y, o.top_marker.z = m + [0.0, 0.03, 0.03]
        obj_pub.publish(o)
        for pub, name in ((js_pub, 'cam2_yaw'), (js9_pub, 'cam9_yaw')):
            js = JointState(name=[name], position=[YAW])
            js.header.stamp = now
            pub.publish(js)

    def spin(pred: Callable[[], bool], timeout: float) -> bool:
        def step() -> bool:
            publish_states()
            return pred()

        return spin_until([cam, imager, blind, peer], step, timeout=timeout)

    assert spin(
        lambda: req_pub.get_subscription_count() >= 3 and obj_pub.get_subscription_count() >= 1,
        20.0,
    )
    t_j = peer.get_clock().now().nanoseconds * 1e-9 + 0.3
    req = CaptureRequest(demand_index=4, camera_ids=['cam2', 'cam9'])
    req.demand_instant.sec = int(t_j)
    req.demand_instant.nanosec = int((t_j - int(t_j)) * 1e9)
    req.predicted_normal.y = -1.0
    req_pub.publish(req)
    assert spin(lambda: len(got) >= 2, 20.0), f'got {[(g.camera_id, g.status) for g in got]}'
    by_cam = {g.camera_id: g for g in got}
    ok = by_cam['cam2']
    assert ok.status == MarkerObservation.STATUS_OK, ok.reason
    assert ok.demand_index == 4
    pos = np.array([ok.position.x, ok.position.y, ok.position.z])
    assert np.linalg.norm(pos - MARKER) < 1e-3
    nrm = np.array([ok.normal.x, ok.normal.y, ok.normal.z])
    assert math.degrees(math.acos(min(1.0, nrm @ [0.0, -1.0, 0.0]))) < 1.0
    assert ok.distance == pytest.approx(0.55, abs=0.01)
    assert ok.bearing == pytest.approx(BEARING, abs=math.radians(2.0))
    cov = np.array(ok.covariance).reshape(6, 6)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    assert by_cam['cam9'].status == MarkerObservation.STATUS_NO_IMAGE
    assert 'no frame' in by_cam['cam9'].reason

    # The object leaves the camera's view: the imager says NOT_FOUND, it does not go silent.
    state['marker'] = MARKER + [0.3, 0.0, 0.0]
    got.clear()
    t_k = peer.get_clock().now().nanoseconds * 1e-9 + 0.3
    req.demand_index = 5
    req.camera_ids = ['cam2']
    req.demand_instant.sec = int(t_k)
    req.demand_instant.nanosec = int((t_k - int(t_k)) * 1e9)
    req_pub.publish(req)
    assert spin(lambda: len(got) >= 1, 20.0)
    assert got[0].status in (MarkerObservation.STATUS_NOT_FOUND, MarkerObservation.STATUS_REJECTED)
    assert got[0].reason


def test_bad_parameters_are_rejected(nodes: Any) -> None:
    cam, imager, _, _ = nodes
    assert not imager.set_parameters([Parameter('marker_radius', value=-0.01)])[0].successful
    assert not imager.set_parameters([Parameter('frame_timeout', value=math.nan)])[0].successful
    assert not cam.set_parameters([Parameter('supersample', value=0)])[0].successful
    assert not cam.set_parameters([Parameter('camera_type', value='fisheye')])[0].successful


def test_a_late_state_delays_the_frame_instead_of_rendering_a_stale_pose(
    nodes: Any, spin_until: Callable[..., bool]
) -> None:
    """On a loaded machine the object states can arrive after the demand instant. The camera
    must wait for them and render the interpolated pose, not hold the last known one."""
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState

    from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, ObjectState

    cam, imager, _, peer = nodes
    assert cam.set_parameters([Parameter('state_hold', value=2.0)])[0].successful
    obj_pub = peer.create_publisher(ObjectState, topics.OBJECT_STATE, qos.SENSOR_RELIABLE)
    js_pub = peer.create_publisher(JointState, topics.joint_states('cam2'), qos.SENSOR_RELIABLE)
    req_pub = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS)
    got: list[MarkerObservation] = []
    peer.create_subscription(MarkerObservation, topics.MARKER_OBSERVATIONS, got.append, qos.EVENTS)

    def stamp(t: float) -> Time:
        return Time(sec=int(t), nanosec=int((t - int(t)) * 1e9))

    def now() -> float:
        return float(peer.get_clock().now().nanoseconds * 1e-9)

    def publish_object(t: float, marker: np.ndarray) -> None:
        o = ObjectState(in_workspace=True)
        o.header.stamp = stamp(t)
        o.side_marker.x, o.side_marker.y, o.side_marker.z = marker
        o.side_normal.y = -1.0
        o.top_marker.x, o.top_marker.y, o.top_marker.z = marker + [0.0, 0.03, 0.03]
        obj_pub.publish(o)

    def publish_joints() -> None:
        js = JointState(name=['cam2_yaw'], position=[YAW])
        js.header.stamp = stamp(now())
        js_pub.publish(js)

    assert spin_until(
        [cam, imager, peer],
        lambda: req_pub.get_subscription_count() >= 2 and obj_pub.get_subscription_count() >= 1,
        timeout=20.0,
    )
    t_j = now() + 0.3
    last = t_j - 0.1  # the last object state before the demand instant
    req = CaptureRequest(demand_index=7, camera_ids=['cam2'], demand_instant=stamp(t_j))
    req.predicted_normal.y = -1.0
    req_pub.publish(req)

    def before() -> bool:
        publish_joints()
        publish_object(min(now(), last), MARKER)
        return now() > t_j + 0.4  # well past trigger_delay (0.05 s)

    frames = cam.frames_published
    spin_until([cam, imager, peer], before, timeout=5.0)
    assert cam.frames_published == frames, 'rendered before the state at the instant arrived'

    shifted = MARKER + [0.012, 0.0, 0.0]
    after = t_j + 0.05  # the marker moved 12 mm between `last` and `after`

    def late() -> bool:
        publish_joints()
        publish_object(after, shifted)
        return bool(got)

    assert spin_until([cam, imager, peer], late, timeout=10.0)
    obs = got[0]
    assert obs.status == MarkerObservation.STATUS_OK, obs.reason
    expected = MARKER + (t_j - last) / (after - last) * (shifted - MARKER)  # 8 mm along x
    pos = np.array([obs.position.x, obs.position.y, obs.position.z])
    assert np.linalg.norm(pos - expected) < 1e-3, (pos - MARKER, expected - MARKER)
