"""The camera node opens what OpenCV opens and publishes best effort, as camera drivers do; the
table runner streams a path to a table controller and reports its positions as truth."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from rclpy.parameter import Parameter

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.ros import qos, topics
from activesurv_hardware.camera_node import CameraNode
from activesurv_hardware.path_runner import PathRunner, TruthFromController
from activesurv_hardware.video_source import VideoSource, is_file, parse_device
from activesurv_sim.xytable import named_path

pytestmark = pytest.mark.node  # in-process rclpy nodes


@pytest.fixture
def video(tmp_path: Path) -> Path:
    path = tmp_path / 'disc.avi'
    w = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*'MJPG'), 20, (320, 240), False)
    assert w.isOpened()
    for i in range(12):
        img = np.full((240, 320), 30, np.uint8)
        cv2.circle(img, (100 + 5 * i, 120), 30, 220, -1)
        w.write(img)
    w.release()
    return path


def test_devices_are_told_apart() -> None:
    assert parse_device('0') == (0, cv2.CAP_ANY)
    assert parse_device('videotestsrc ! appsink')[1] == cv2.CAP_GSTREAMER
    assert parse_device('rtsp://cam/stream')[1] == cv2.CAP_FFMPEG
    assert is_file('/data/run.avi')
    assert not is_file('/dev/video0')
    assert not is_file('2')


def test_a_video_file_plays_and_loops(video: Path) -> None:
    src = VideoSource(str(video), loop=True)
    src.open()
    frames = [src.read() for _ in range(30)]  # more than the file holds
    assert frames[0].shape[:2] == (240, 320)
    assert src.frames == 30
    src.close()


def test_a_missing_device_is_an_error_not_a_crash(tmp_path: Path) -> None:
    from activesurv_hardware.errors import CameraSourceError

    src = VideoSource(str(tmp_path / 'none.avi'))
    with pytest.raises(CameraSourceError, match='cannot open'):
        src.open()
    assert src.failures == 1


def test_camera_node_publishes_best_effort_with_camera_info(
    rclpy_context: Any, spin_until: Callable[..., bool], video: Path, tmp_path: Path
) -> None:
    from sensor_msgs.msg import CameraInfo, Image

    cam = dynamic_camera('cam7')
    info_file = tmp_path / 'cam7.yaml'
    cam.save(info_file)
    node = CameraNode(
        parameter_overrides=[
            Parameter('camera_id', value='cam7'),
            Parameter('device', value=str(video)),
            Parameter('frame_rate', value=40.0),
            Parameter('loop', value=True),
            Parameter('camera_info_file', value=str(info_file)),
        ]
    )
    peer = rclpy_context.create_node('camera_test_peer')
    images: list[Any] = []
    infos: list[Any] = []
    try:
        peer.create_subscription(Image, topics.image('cam7'), images.append, qos.SENSOR)
        peer.create_subscription(CameraInfo, topics.camera_info('cam7'), infos.append, qos.SENSOR)
        assert spin_until([peer], lambda: len(images) >= 20, timeout=20.0)
        assert images[0].encoding == 'mono8'
        assert (images[0].width, images[0].height) == (320, 240)
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in images]
        assert all(b > a for a, b in itertools.pairwise(stamps))
        rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
        assert 20.0 < rate < 60.0  # a file plays at frame_rate (40 Hz), roughly
        assert infos
        assert infos[0].width == cam.width
    finally:
        node.close()
        node.destroy_node()
        peer.destroy_node()


def test_the_path_is_streamed_in_short_timed_moves() -> None:
    path = named_path('parabola', [0.13, 0.05, 0.25, 0.09, 0.37, 0.05], 0.02, 0.02)
    runner = PathRunner(path, start_time=1.0, segment=0.1, lead=0.3)
    approach = runner.move(0.0)
    assert approach is not None
    assert np.allclose([approach.x, approach.y], path.position(0.0))
    assert runner.move(0.05) is None  # the approach is sent once
    moves = []
    t = 0.7
    while t < runner.end_time + 1.0:
        m = runner.move(t)
        if m is not None:
            moves.append((t, m))
        t += 0.05
    # Each move ends on the path, lead s ahead of the clock, at the path's speed.
    for t, m in moves[:-1]:
        tau = min(t - 1.0 + 0.3, path.duration)
        assert np.allclose([m.x, m.y], path.position(tau), atol=1e-9)
        assert m.speed <= 0.02 + 1e-6
    last = moves[-1][1]
    assert np.allclose([last.x, last.y], path.position(path.duration))
    gaps = np.diff([t for t, _ in moves])
    assert np.all(gaps[:-1] >= 0.1 - 1e-9)  # about lead / segment moves queued, not a flood


def test_truth_is_the_reported_carriage_through_the_object_model() -> None:
    model = ObjectGeometry(0.08, (0.0, -0.03, -0.03), (0.0, -1.0, 0.0))
    truth = TruthFromController(model)
    a = truth.state(1.0, np.array([0.2, 0.1]))
    b = truth.state(1.5, np.array([0.21, 0.1]))
    assert np.allclose(a.side, [0.2, 0.07, 0.05])
    assert np.allclose(b.velocity, [0.02, 0.0, 0.0])
    assert b.moving


def test_a_software_triggered_camera_node_publishes_one_frame_per_call(
    rclpy_context: Any, spin_until: Callable[..., bool], video: Path
) -> None:
    from sensor_msgs.msg import Image
    from std_srvs.srv import Trigger

    node = CameraNode(
        parameter_overrides=[
            Parameter('camera_id', value='cam8'),
            Parameter('device', value=str(video)),
            Parameter('frame_rate', value=40.0),
            Parameter('loop', value=True),
            Parameter('trigger', value='software'),
            Parameter('exposure_delay', value=0.01),
        ]
    )
    peer = rclpy_context.create_node('trigger_test_peer')
    images: list[Any] = []
    try:
        peer.create_subscription(Image, topics.image('cam8'), images.append, qos.SENSOR)
        client = peer.create_client(Trigger, 'camera/trigger')
        assert client.wait_for_service(timeout_sec=10.0)
        assert spin_until([peer, node], lambda: node.source.frames >= 10, timeout=10.0)
        assert not images  # streaming, but nothing published until asked
        calls = []
        for n in range(5):
            called = peer.get_clock().now().nanoseconds * 1e-9
            future = client.call_async(Trigger.Request())
            assert spin_until([peer, node], future.done, timeout=5.0)
            assert future.result().success
            calls.append(called)
            assert spin_until([peer, node], lambda n=n: len(images) > n, timeout=5.0)
        assert spin_until([peer, node], lambda: node.source.frames >= 40, timeout=10.0)
        assert len(images) == 5  # one frame per call, no other
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in images]
        exposed = [s - 0.01 for s in stamps]
        # Each frame began exposing after its call, within a frame period (40 Hz) and jitter.
        offsets = [e - c for e, c in zip(exposed, calls, strict=True)]
        assert all(0.0 <= o < 0.025 + 0.05 for o in offsets), offsets
        assert node.triggers == 5
        assert node.published == 5
        assert node.skipped >= 30
    finally:
        node.close()
        node.destroy_node()
        peer.destroy_node()
