"""Camera model: Table I defaults, projection, distortion, YAML round trip (no ROS)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from activesurv_common.camera_model import CameraModel, dynamic_camera, overhead_camera
from activesurv_common.errors import CalibrationError


def test_table_one_defaults() -> None:
    cam = dynamic_camera()
    assert (cam.width, cam.height) == (640, 480)
    # The 25 mm marker spans about 200-250 px at working distance (paper, Section III-A).
    for d, lo, hi in ((0.5, 245, 255), (0.6, 200, 215)):
        px = cam.project(np.array([[-0.0125, 0, d], [0.0125, 0, d]]))
        assert lo <= px[1, 0] - px[0, 0] <= hi
    top = overhead_camera()
    assert top.fx == pytest.approx(1200.0)


def test_distortion_round_trip_and_yaml(tmp_path: Path) -> None:
    cam = CameraModel(640, 480, dynamic_camera().K, [-0.2, 0.05, 1e-3, -5e-4, 0.0], 'cam2')
    pts = np.array([[0.01, -0.02, 0.5], [-0.03, 0.02, 0.6], [0.0, 0.0, 0.55]])
    px = cam.project(pts)
    rays = cam.rays(px)
    assert np.allclose(rays[:, :2], pts[:, :2] / pts[:, 2:3], atol=1e-10)
    path = tmp_path / 'cam2.yaml'
    cam.save(path)
    back = CameraModel.load(path)
    assert back.name == 'cam2'
    assert np.allclose(back.K, cam.K)
    assert np.allclose(back.dist, cam.dist)


@pytest.mark.parametrize(
    'text',
    ['just a string', 'image_width: 640\n', 'camera_matrix: {data: [1, 2]}\n', ': :'],
)
def test_malformed_yaml_is_a_clear_error(tmp_path: Path, text: str) -> None:
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(CalibrationError):
        CameraModel.load(path)


def test_invalid_intrinsics() -> None:
    with pytest.raises(CalibrationError, match='fx, fy'):
        CameraModel(640, 480, np.diag([-1.0, 1.0, 1.0]))
    with pytest.raises(CalibrationError, match='size'):
        CameraModel(0, 480, np.eye(3))


def test_the_calibration_file_is_what_camera_calibration_writes(tmp_path: Path) -> None:
    import yaml

    from activesurv_common.camera_model import dynamic_camera

    cam = dynamic_camera('cam1')
    cam.save(tmp_path / 'cam1.yaml')
    doc = yaml.safe_load((tmp_path / 'cam1.yaml').read_text())
    # camera_calibration_parsers reads all of these unconditionally (a driver's
    # camera_info_manager refuses a file without them).
    for key in (
        'image_width',
        'image_height',
        'camera_name',
        'camera_matrix',
        'distortion_model',
        'distortion_coefficients',
        'rectification_matrix',
        'projection_matrix',
    ):
        assert key in doc, key
    assert doc['rectification_matrix']['data'] == [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0]
    P = np.array(doc['projection_matrix']['data']).reshape(3, 4)
    assert np.allclose(P[:, :3], cam.K)
    assert np.allclose(P[:, 3], 0.0)
