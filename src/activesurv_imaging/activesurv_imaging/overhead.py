"""Overhead fixes: the top marker's world (x, y) from one overhead image (pure core).

The top marker moves in the horizontal plane z = ``marker_height``; the image and the overhead
camera's calibration (intrinsics + ``T_world_camera``, from ``activesurv_calibrate``) fix it.
The ``overhead_locator`` node publishes these fixes; the predictor tracks them.
The imaging package's pipeline finds the marker (detection and weighted ellipse fit are not
written twice); the circle pose gives the ray through the true circle centre (not the ellipse
centre, which perspective shifts), and that ray meets the marker plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_imaging.detect import DetectorConfig, detect_markers
from activesurv_imaging.marker_pose import MarkerMeasurement, MeasurementStatus, measure_marker

Array = NDArray[np.float64]

# The top marker is small in the overhead image (25 mm from 1.2 m: about 25 px across).
OVERHEAD_DETECTOR = DetectorConfig(min_semi_minor=3.0, max_semi_major=120.0)


@dataclass(frozen=True)
class OverheadFix:
    """A fix, or why there is none.

    Attributes:
        xy: (2,) world position of the top marker, or None.
        reason: why not, when ``xy`` is None.
    """

    xy: Array | None
    reason: str = ''


def overhead_fix(
    image: ArrayLike,
    camera: CameraModel,
    T_world_camera: Transform,
    marker_height: float,
    radius: float,
    config: DetectorConfig = OVERHEAD_DETECTOR,
) -> OverheadFix:
    """Locate the top marker in an overhead image."""
    up_in_camera = T_world_camera.inverse().rotate([0.0, 0.0, 1.0])
    m = measure_marker(image, camera, radius, up_in_camera, config=config)
    return _on_plane(m, T_world_camera, marker_height)


def overhead_fixes(
    image: ArrayLike,
    camera: CameraModel,
    T_world_camera: Transform,
    marker_height: float,
    radius: float,
    config: DetectorConfig = OVERHEAD_DETECTOR,
) -> list[OverheadFix]:
    """Every top marker in an overhead image (several objects on the table): a fix each,
    or why that marker gave none."""
    up_in_camera = T_world_camera.inverse().rotate([0.0, 0.0, 1.0])
    out = []
    for det in detect_markers(image, config):
        m = measure_marker(image, camera, radius, up_in_camera, config=config, detection=det)
        out.append(_on_plane(m, T_world_camera, marker_height))
    return out


def _on_plane(m: MarkerMeasurement, T_world_camera: Transform, height: float) -> OverheadFix:
    """Where the ray through a measured marker's centre meets the plane z = ``height``."""
    if m.status is not MeasurementStatus.OK or m.pose is None:
        return OverheadFix(None, m.reason or m.status.name)
    ray = T_world_camera.rotate(m.pose.center)
    if abs(ray[2]) < 1e-9:
        return OverheadFix(None, 'the ray to the marker is parallel to the marker plane')
    s = (height - T_world_camera.t[2]) / ray[2]
    if not (math.isfinite(s) and s > 0.0):
        return OverheadFix(None, 'the marker plane is behind the overhead camera')
    p = T_world_camera.t + s * ray
    return OverheadFix(np.asarray(p[:2], dtype=np.float64))


def load_extrinsics(path: Path | str) -> Transform:
    """``T_world_camera`` from a YAML written by ``activesurv_calibrate extrinsics``.

    Raises:
        CalibrationError: if the file is missing or malformed.
    """
    try:
        data = yaml.safe_load(Path(path).read_text())
        T = data['T_world_camera']
        return Transform.from_rt(matrix_from_quaternion(T['rotation_xyzw']), T['translation'])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise CalibrationError(f'cannot read overhead extrinsics {path}: {exc}') from exc
