"""Core tests of the circle pose from an ellipse (Appendix B, no ROS)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.geometry import angle_between, rotation_between
from activesurv_imaging.circle_pose import choose_pose, circle_poses
from activesurv_imaging.ellipse import Ellipse, fit_ellipse
from activesurv_imaging.errors import CirclePoseError

CAM = dynamic_camera()
RADIUS = 0.0125


def _image_of_circle(center: np.ndarray, normal: np.ndarray) -> Ellipse:
    R = rotation_between([0, 0, 1], normal)
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    pts = center + RADIUS * (np.outer(np.cos(t), R[:, 0]) + np.outer(np.sin(t), R[:, 1]))
    return fit_ellipse(CAM.project(pts))


@settings(max_examples=150, deadline=None)
@given(
    st.floats(0.4, 0.8),
    st.floats(-0.01, 0.01),
    st.floats(-0.01, 0.01),
    st.floats(0.0, 1.2),
    st.floats(-np.pi, np.pi),
)
def test_one_of_the_two_poses_is_the_truth(
    depth: float, ox: float, oy: float, bearing: float, az: float
) -> None:
    center = np.array([ox, oy, depth])
    to_cam = -center / np.linalg.norm(center)
    perp = np.cross(to_cam, [np.cos(az), np.sin(az), 0.0])
    perp /= np.linalg.norm(perp)
    normal = np.cos(bearing) * to_cam + np.sin(bearing) * perp
    poses = circle_poses(_image_of_circle(center, normal), CAM.K, RADIUS)
    for p in poses:
        assert p.normal @ p.center < 0  # normals point towards the camera
        assert np.linalg.norm(p.normal) == pytest.approx(1.0)
    err = min(np.linalg.norm(p.center - center) for p in poses)
    ang = min(angle_between(p.normal, normal) for p in poses)
    assert err < 1e-8
    assert ang < 1e-6
    idx, margin = choose_pose(poses, normal)
    assert angle_between(poses[idx].normal, normal) < 1e-6
    assert margin >= 0.0


def test_frontal_circle_has_one_solution_twice() -> None:
    center = np.array([0.0, 0.0, 0.5])
    a, b = circle_poses(_image_of_circle(center, np.array([0.0, 0.0, -1.0])), CAM.K, RADIUS)
    assert np.allclose(a.center, b.center, atol=1e-9)
    assert np.allclose(a.center, center, atol=1e-9)


def test_bad_inputs() -> None:
    ell = Ellipse(np.array([320.0, 240.0]), (100.0, 80.0), 0.0)
    with pytest.raises(CirclePoseError, match='radius'):
        circle_poses(ell, CAM.K, -1.0)
    with pytest.raises(CirclePoseError, match='camera_matrix'):
        circle_poses(ell, np.zeros((3, 3)), RADIUS)
