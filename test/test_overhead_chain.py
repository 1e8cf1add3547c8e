"""Node test: rendered overhead images -> overhead_locator -> predictor -> a DemandHorizon."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_imaging.overhead_locator_node import OverheadLocatorNode
from activesurv_prediction.predictor_node import PredictorNode
from activesurv_sim.sim_camera_node import SimCameraNode

pytestmark = pytest.mark.node  # in-process rclpy nodes

OVERHEAD_POSE = [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0]  # looking straight down
TOP_HEIGHT = 0.08


def test_images_to_demand_horizon(rclpy_context: Any, spin_until: Callable[..., bool]) -> None:
    from activesurv_interfaces.msg import DemandHorizon, ObjectState

    t0 = time.time()
    demands = [t0 + 6.0, t0 + 8.0, t0 + 10.0]
    cam = SimCameraNode(
        parameter_overrides=[
            Parameter('camera_id', value='overhead'),
            Parameter('camera_type', value='overhead'),
            Parameter('mount.static_pose', value=OVERHEAD_POSE),
            Parameter('frame_rate', value=15.0),
            Parameter('supersample', value=4),
        ]
    )
    locator = OverheadLocatorNode(
        parameter_overrides=[
            Parameter('camera_pose', value=OVERHEAD_POSE),
            Parameter('marker_height', value=TOP_HEIGHT),
        ]
    )
    pred = PredictorNode(
        parameter_overrides=[
            Parameter('demand_times', value=demands),
            Parameter('marker_height', value=TOP_HEIGHT),
            Parameter('confirm_fixes', value=5),
            Parameter('horizon', value=2),
        ]
    )
    peer = rclpy_context.create_node('predictor_test_peer')
    horizons: list[DemandHorizon] = []
    peer.create_subscription(DemandHorizon, topics.DEMAND_HORIZON, horizons.append, qos.LATCHED)
    obj_pub = peer.create_publisher(ObjectState, 'object_state', qos.SENSOR)

    def truth(t: float) -> np.ndarray:
        return np.array([0.15 + 0.015 * (t - t0), 0.08 + 0.005 * (t - t0)])

    def step() -> bool:
        now = peer.get_clock().now()
        xy = truth(now.nanoseconds * 1e-9)
        o = ObjectState(in_workspace=True)
        o.header.stamp = now.to_msg()
        o.top_marker.x, o.top_marker.y, o.top_marker.z = xy[0], xy[1], TOP_HEIGHT
        o.side_marker.x, o.side_marker.y, o.side_marker.z = xy[0], xy[1] - 0.03, TOP_HEIGHT - 0.03
        o.side_normal.y = -1.0
        obj_pub.publish(o)
        return (
            bool(horizons)
            and horizons[-1].track_state == DemandHorizon.TRACK_CONFIRMED
            and time.time() > t0 + 3.0
        )

    try:
        assert spin_until([cam, locator, pred, peer], step, timeout=40.0), (
            f'horizons: {len(horizons)}, last state '
            f'{horizons[-1].track_state if horizons else None}'
        )
        h = horizons[-1]
        assert [d.index for d in h.demands] == [0, 1]
        d0 = h.demands[0]
        t_j = d0.demand_instant.sec + 1e-9 * d0.demand_instant.nanosec
        assert abs(t_j - demands[0]) < 1e-6
        expected = np.r_[truth(t_j), TOP_HEIGHT] + [0.0, -0.03, -0.03]
        got = np.array([d0.pose.pose.position.x, d0.pose.pose.position.y, d0.pose.pose.position.z])
        assert np.linalg.norm(got - expected) < 0.01  # a few seconds ahead, few fixes so far
        cov = np.array(d0.pose.covariance).reshape(6, 6)
        assert cov[0, 0] > 0.0
        assert (d0.normal.x, d0.normal.y, d0.normal.z) == (0.0, -1.0, 0.0)
    finally:
        for n in (cam, locator, pred, peer):
            n.destroy_node()


def test_a_containers_overhead_frames_reach_the_locator_in_process(rclpy_context: Any) -> None:
    """In a container (``local_topics`` enabled, the camera built first, as the graph puts
    the overhead camera and its locator in one process) each frame is located when it is
    published, without a spin and without a copy through DDS (no reader of it there)."""
    from sensor_msgs.msg import Image

    from activesurv_common.ros import local_topics

    local_topics.enable()
    camera = rclpy_context.create_node('overhead_camera', namespace='/lt_over')
    try:
        pub = local_topics.publisher(camera, Image, 'overhead/image_raw', qos.SENSOR_RELIABLE)
        locator = OverheadLocatorNode(
            namespace='/lt_over',
            parameter_overrides=[
                Parameter('camera_pose', value=OVERHEAD_POSE),
                Parameter('marker_height', value=TOP_HEIGHT),
            ],
        )
    finally:
        local_topics.enable(False)
    try:
        msg = Image(height=4, width=4, step=4, encoding='mono8', data=bytes(16))
        msg.header.frame_id = 'overhead_optical_frame'
        pub.publish(msg)
        assert locator.counts['frames'] == 1  # handled in the publish call itself
        assert locator.last_reason == 'waiting for camera_info'
        assert pub.get_subscription_count() == 0  # no DDS reader: no copy of it through DDS
    finally:
        locator.destroy_node()
        camera.destroy_node()


def test_a_containers_horizon_and_track_reach_dispatcher_and_frames_in_process(
    rclpy_context: Any,
) -> None:
    """In the graph's ``core`` container (predictor, dispatcher, frames, in that order) the
    horizon reaches the dispatcher and the accepted fix the frames node in the predictor's
    publish call, with no DDS reader of them in the process: the recorder alone hears them
    over DDS."""
    from geometry_msgs.msg import PointStamped

    from activesurv_common.ros import local_topics
    from activesurv_dispatch.dispatcher_node import DispatcherNode
    from activesurv_interfaces.msg import DemandHorizon
    from activesurv_liveview.frames_node import FramesNode

    local_topics.enable()
    try:
        predictor = PredictorNode(namespace='/lt_core')
        dispatcher = DispatcherNode(namespace='/lt_core')
        frames = FramesNode(namespace='/lt_core')
    finally:
        local_topics.enable(False)
    try:
        horizon = DemandHorizon()
        horizon.header.stamp.sec = 7
        predictor._horizon_pub.publish(horizon)
        assert dispatcher.session.horizon_stamp == 7.0  # handled in the publish call itself
        track = PointStamped()
        track.header.stamp.sec, track.header.frame_id = 7, 'world'
        before = len(frames._pending)
        predictor._track_pub.publish(track)
        sent = frames._pending[before:] if frames._batched else []
        assert not frames._batched or [t.child_frame_id for t in sent] == ['object']
        assert predictor._horizon_pub.get_subscription_count() == 0  # no DDS reader here
        assert predictor._track_pub.get_subscription_count() == 0
    finally:
        for node in (frames, dispatcher, predictor):
            node.destroy_node()
