"""A demand instant's camera pose is worked out when the stage state of the instant arrives
(published ahead, from the commanded profile), and taken from there when the frame comes; a
new state of the instant (a new goal) replaces it."""

from __future__ import annotations

import numpy as np

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.mount import CameraMount
from activesurv_common.sensor_model import SensorModel
from activesurv_imaging.capture import CaptureCore, ImagerConfig

T = 2.0


def _core() -> CaptureCore[np.ndarray]:
    mount = CameraMount('cam1', np.array([0.02, -0.5, 0.05]), 1.5708, 0.0, np.zeros(3))
    config = ImagerConfig('cam1', 0.0125)
    return CaptureCore(config, mount, SensorModel.load(None), lambda g: g, dynamic_camera('cam1'))


def _same(a: object, b: object) -> bool:
    return bool(np.array_equal(a.R, b.R) and np.array_equal(a.t, b.t))  # type: ignore[attr-defined]


def test_the_pose_of_an_instant_is_ready_before_its_frame_and_follows_a_new_state() -> None:
    core = _core()
    assert isinstance(core.mount, CameraMount)
    core.add_joints(T - 0.1, [0.0])
    core.request(0, T, [0.0, -1.0, 0.0])
    assert core.add_joints(T, [0.3])  # the stage's state of the instant, ahead
    ahead = core.camera_pose(T)
    assert ahead is not None
    assert ahead is core.camera_pose(T)  # worked out once
    assert _same(ahead, core.mount.pose_from_joints([0.3]))
    core.add_joints(T, [0.4])  # a new goal: the instant's state again
    again = core.camera_pose(T)
    assert again is not None
    assert _same(again, core.mount.pose_from_joints([0.4]))
    # Between samples and without a request, the pose is interpolated as before.
    between = core.camera_pose(T - 0.05)
    assert between is not None
    assert np.allclose(between.R, core.mount.pose_from_joints([0.2]).R, atol=1e-12)


def test_a_request_after_its_state_gets_the_pose_ahead_too() -> None:
    core = _core()
    core.add_joints(T, [0.25])  # the state came first (the stage's call ran first)
    core.request(0, T, [0.0, -1.0, 0.0])
    first = core.camera_pose(T)
    assert first is not None
    assert first is core.camera_pose(T)
