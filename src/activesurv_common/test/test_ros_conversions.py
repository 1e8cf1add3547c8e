"""Message conversions of the imaging package: CameraInfo, Image, mount parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from sensor_msgs.msg import Image

from activesurv_common.camera_model import CameraModel, dynamic_camera
from activesurv_common.errors import CalibrationError, ImageFormatError
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_common.ros.conversions import (
    MOUNT_PARAMETERS,
    CameraInfoStamper,
    camera_info_from_model,
    gray_to_image,
    image_to_gray,
    model_from_camera_info,
    mount_from_parameters,
    sec_to_time,
    time_to_sec,
)


def test_camera_info_round_trip() -> None:
    cam = CameraModel(640, 480, dynamic_camera().K, [-0.1, 0.01, 0.0, 0.0, 0.0], 'cam3')
    info = camera_info_from_model(cam, 'cam3_optical', Time(sec=3))
    back = model_from_camera_info(info, 'cam3')
    assert np.allclose(back.K, cam.K)
    assert np.allclose(back.dist, cam.dist)
    assert info.p[0] == cam.fx
    info.distortion_model = 'equidistant'
    with pytest.raises(CalibrationError, match='equidistant'):
        model_from_camera_info(info, 'cam3')


def test_a_stamper_gives_each_frame_its_own_header_on_the_same_intrinsics() -> None:
    cam = CameraModel(640, 480, dynamic_camera().K, [-0.1, 0.01, 0.0, 0.0, 0.0], 'cam3')
    stamper = CameraInfoStamper(cam, 'cam3_optical')
    first, second = stamper(Time(sec=3, nanosec=5)), stamper(Time(sec=4))
    assert (first.header.stamp.sec, first.header.stamp.nanosec) == (3, 5)  # not the second's
    assert second.header.stamp.sec == 4
    assert second.header.frame_id == 'cam3_optical'
    for stamp, msg in ((Time(sec=3, nanosec=5), first), (Time(sec=4), second)):
        assert msg == camera_info_from_model(cam, 'cam3_optical', stamp)


def test_image_encodings_and_bad_buffers() -> None:
    gray = (np.arange(48, dtype=np.uint8) * 5).reshape(6, 8)
    msg = gray_to_image(gray, 'f', Time())
    assert np.array_equal(image_to_gray(msg), gray)
    rgb = Image(
        height=6,
        width=8,
        encoding='rgb8',
        step=24,
        data=np.repeat(gray[:, :, None], 3, axis=2).tobytes(),
    )
    assert np.array_equal(image_to_gray(rgb), gray)
    with pytest.raises(ImageFormatError, match='encoding'):
        image_to_gray(Image(height=6, width=8, encoding='32FC1', step=32, data=bytes(192)))
    with pytest.raises(ImageFormatError, match='does not match'):
        image_to_gray(Image(height=6, width=8, encoding='mono8', step=8, data=bytes(10)))


def test_time_round_trip() -> None:
    for t in (0.0, 1.5, 1234.000000001, 99.999999999):
        assert time_to_sec(sec_to_time(t)) == pytest.approx(t, abs=1e-9)
    assert time_to_sec(sec_to_time(math.nan)) == 0.0


def test_mount_parameters() -> None:
    values = {k: v for k, (v, _) in MOUNT_PARAMETERS.items()}
    values['mount.base'] = [0.1, -0.5, 0.05]
    values['mount.linear_axis'] = [1.0, 0.0, 0.0]
    mount = mount_from_parameters('cam1', values)
    assert isinstance(mount, CameraMount)
    assert mount.joint_names == ('cam1_x', 'cam1_yaw')
    values['mount.static_pose'] = [0.0, 0.0, 1.2, 1.0, 0.0, 0.0, 0.0]
    static = mount_from_parameters('overhead', values)
    assert isinstance(static, Transform)
    assert np.allclose(static.R[:, 2], [0.0, 0.0, -1.0])  # looking down
    values['mount.static_pose'] = [0.0, 1.0]
    with pytest.raises(CalibrationError, match='7 numbers'):
        mount_from_parameters('overhead', values)
