"""Marker detection on rendered pixels: the marker, and every kind of non-marker (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.geometry import angle_between
from activesurv_imaging.circle_pose import choose_pose, circle_poses
from activesurv_imaging.detect import (
    DetectionStatus,
    detect_marker,
    detect_marker_detailed,
)
from activesurv_imaging.errors import ImagingError
from activesurv_sim.render import Plate, Scene, SensorNoise, look_at, render

CAM = dynamic_camera()
MARKER = np.array([0.2, 0.1, 0.05])
NORMAL = np.array([0.0, -1.0, 0.0])


def _view(
    eye_dir: tuple[float, float, float],
    d: float = 0.55,
    aim: np.ndarray = MARKER,
    plates: tuple[Plate, ...] | None = None,
    seed: int = 0,
) -> tuple[np.ndarray, object]:
    direction = np.asarray(eye_dir) / np.linalg.norm(eye_dir)
    T = look_at(MARKER + d * direction, aim)
    scene = Scene(plates or (Plate.disc(MARKER, NORMAL, 0.0125),))
    return render(CAM, T, scene, rng=np.random.default_rng(seed)), T


@pytest.mark.parametrize('eye_dir', [(0.0, -1.0, 0.0), (0.5, -0.8, 0.1), (-0.6, -0.6, -0.3)])
def test_marker_pose_from_rendered_pixels(eye_dir: tuple[float, float, float]) -> None:
    img, T = _view(eye_dir)
    ell = detect_marker(img)
    assert ell is not None
    assert 180 < 2 * ell.semi_axes[0] < 260
    poses = circle_poses(ell, CAM.K, 0.0125)
    Tinv = T.inverse()  # type: ignore[attr-defined]
    idx, _ = choose_pose(poses, Tinv.rotate(NORMAL))
    assert np.linalg.norm(poses[idx].center - Tinv.apply(MARKER)) < 0.5e-3
    # Head-on, the tilt of a circle is ill-conditioned (the paper's best bearing is 20-40 deg):
    # over 12 noise seeds its normal error has a median of 0.42-0.48 deg and a max of 0.63 deg
    # with either anti-aliasing; oblique views stay under 0.01 deg.
    limit = 1.0 if eye_dir == (0.0, -1.0, 0.0) else 0.05
    assert np.degrees(angle_between(poses[idx].normal, Tinv.rotate(NORMAL))) < limit


def test_no_marker_black_and_saturated_frames() -> None:
    for frame in (np.zeros((480, 640), np.uint8), np.full((480, 640), 255, np.uint8)):
        det = detect_marker_detailed(frame)
        assert det.status is DetectionStatus.NOT_FOUND
        assert 'contrast' in det.reason
    plate_only = Plate(MARKER, NORMAL, np.array([1.0, 0, 0]), (0.06, 0.06))
    img, _ = _view((0.0, -1.0, 0.0), plates=(plate_only,))
    det = detect_marker_detailed(img)
    assert det.status is not DetectionStatus.OK
    assert detect_marker(img) is None


def test_two_markers_are_rejected() -> None:
    plates = (
        Plate.disc(MARKER + [-0.016, 0, 0], NORMAL, 0.006, 0.0079),
        Plate.disc(MARKER + [0.016, 0, 0], NORMAL, 0.006, 0.0079),
    )
    img, _ = _view((0.0, -1.0, 0.0), plates=plates)
    det = detect_marker_detailed(img)
    assert det.status is DetectionStatus.REJECTED
    assert '2 markers' in det.reason


def test_marker_cut_by_the_image_border_is_rejected() -> None:
    img, _ = _view((0.0, -1.0, 0.0), aim=MARKER + [0.03, 0, 0])
    det = detect_marker_detailed(img)
    assert det.status is DetectionStatus.REJECTED
    assert 'border' in det.reason


def test_square_marker_is_not_an_ellipse() -> None:
    square = Plate(MARKER, NORMAL, np.array([1.0, 0, 0]), (0.011, 0.011), plate_level=230.0)
    plate = Plate(MARKER + [0, 0.001, 0], NORMAL, np.array([1.0, 0, 0]), (0.06, 0.06))
    img, _ = _view((0.0, -1.0, 0.0), plates=(square, plate))
    det = detect_marker_detailed(img)
    assert det.status is DetectionStatus.REJECTED
    assert 'not an ellipse' in det.reason


def test_wrong_size_is_rejected() -> None:
    img, _ = _view((0.0, -1.0, 0.0), d=0.2)  # far too close: ~625 px across
    det = detect_marker_detailed(img)
    assert det.status is not DetectionStatus.OK


def test_non_images_raise() -> None:
    with pytest.raises(ImagingError, match='8-bit'):
        detect_marker(np.zeros((480, 640), np.float32))
    with pytest.raises(ImagingError, match='grey image'):
        detect_marker(np.zeros((4, 4), np.uint8))


def test_rendering_is_seeded_and_anti_aliased() -> None:
    a, _ = _view((0.3, -1.0, 0.0), seed=3)
    b, _ = _view((0.3, -1.0, 0.0), seed=3)
    c, _ = _view((0.3, -1.0, 0.0), seed=4)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    ideal = render(
        CAM,
        look_at(MARKER + [0.0, -0.55, 0.0], MARKER),
        Scene((Plate.disc(MARKER, NORMAL, 0.0125),)),
        SensorNoise(blur_sigma=0.0, electrons_per_level=0.0, read_noise=0.0),
    )
    levels = np.unique(ideal)
    assert len(levels) > 10  # edge pixels hold intermediate, supersampled levels
