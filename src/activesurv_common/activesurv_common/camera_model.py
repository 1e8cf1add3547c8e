"""Pinhole camera with OpenCV distortion (plumb-bob k1, k2, p1, p2, k3).

Pixel coordinates follow OpenCV: x right, y down, integer values at pixel centres. The camera
frame is ``<camera>_optical_frame`` (REP 103): z forward, x right, y down. Defaults come from the
paper's Table I:

* dynamic cameras: 640x480, 1/4-inch CMOS (3.2 x 2.4 mm, 5 um pixels), 25 mm lens:
  fx = fy = 25 mm / 5 um = 5000 px, so the 25 mm marker is 250 px across at 0.5 m and 208 px at
  0.6 m (the paper's "about 200-250 pixels");
* overhead camera: 640x480 CCD with a 12 mm lens. Table I does not give the sensor size; a
  1/2-inch CCD (6.4 x 4.8 mm, 10 um pixels) is assumed: fx = 1200 px, so from 1.2 m it sees
  0.64 m x 0.48 m, the whole 500 x 200 mm table with margin.

YAML files use the ROS ``camera_calibration`` layout (``image_width``, ``camera_matrix``,
``distortion_coefficients``, ...), which OpenCV users and ``camera_info_manager`` both read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from activesurv_common.errors import CalibrationError
from activesurv_common.yamlio import load_yaml

Array = NDArray[np.float64]


def thin_lens_sigma(
    fx: float, focal_length: float, f_number: float, focus_distance: float, distance: ArrayLike
) -> Array:
    """Per-axis standard deviation (px) of the blur circle of points at ``distance`` m for a
    thin lens of ``focal_length`` m at ``f_number`` focused at ``focus_distance`` m, on a camera
    of ``fx`` px focal length: the circle's diameter ``fx (f / N) |d - d_f| / (d (d_f - f))``
    px, a quarter of it (a uniform disc's per-axis std)."""
    f, df = focal_length, focus_distance
    d = np.maximum(np.asarray(distance, dtype=np.float64), f * 1.001)
    circle = fx * (f / f_number) * np.abs(d - df) / (d * (df - f))
    return np.asarray(circle / 4.0, dtype=np.float64)


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics of one camera.

    Attributes:
        width, height: image size in pixels.
        K: 3x3 camera matrix.
        dist: distortion coefficients (k1, k2, p1, p2, k3).
        name: camera id, e.g. ``cam1`` or ``overhead``.
        gamma: the camera's response, ``grey = 255 (radiance / full scale)^(1 / gamma)``
            (1: linear; 2.2: an sRGB-like curve); the imager linearises frames with it.
        exposure_time: s the shutter is open (0: unknown); a moving marker is blurred over it.
        f_number, focus_distance (m), focal_length (m): the lens as set (0: unknown); with
            them the depth of field's blur at a distance is known (:meth:`defocus_sigma`).
    """

    width: int
    height: int
    K: Array
    dist: Array = field(default_factory=lambda: np.zeros(5))
    name: str = 'camera'
    gamma: float = 1.0
    exposure_time: float = 0.0
    f_number: float = 0.0
    focus_distance: float = 0.0
    focal_length: float = 0.0

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=np.float64)
        dist = np.asarray(self.dist, dtype=np.float64).reshape(-1)
        if self.width <= 0 or self.height <= 0:
            raise CalibrationError(f'{self.name}: image size must be positive')
        if K.shape != (3, 3) or not np.all(np.isfinite(K)):
            raise CalibrationError(f'{self.name}: camera matrix must be a finite 3x3 matrix')
        if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
            raise CalibrationError(f'{self.name}: camera matrix needs fx, fy > 0 and [0 0 1]')
        if dist.size not in (0, 4, 5, 8) or not np.all(np.isfinite(dist)):
            raise CalibrationError(f'{self.name}: distortion must have 4, 5 or 8 finite values')
        if not (math.isfinite(self.gamma) and 0.2 <= self.gamma <= 5.0):
            raise CalibrationError(
                f'{self.name}: response gamma must be in [0.2, 5], got {self.gamma}'
            )
        if not (math.isfinite(self.exposure_time) and 0.0 <= self.exposure_time <= 1.0):
            raise CalibrationError(
                f'{self.name}: exposure_time must be in [0, 1] s, got {self.exposure_time}'
            )
        lens = (self.f_number, self.focus_distance, self.focal_length)
        if not all(math.isfinite(v) and v >= 0.0 for v in lens) or (
            any(lens) and not (all(lens) and self.focus_distance > self.focal_length)
        ):
            raise CalibrationError(
                f'{self.name}: lens needs f_number, focus_distance > focal_length > 0 '
                f'(all three, or none), got {lens}'
            )
        object.__setattr__(self, 'K', K)
        object.__setattr__(self, 'dist', np.pad(dist, (0, max(0, 5 - dist.size))))

    @property
    def has_lens(self) -> bool:
        """Whether the lens settings are known (the depth of field can be predicted)."""
        return self.f_number > 0.0

    def defocus_sigma(self, distance: ArrayLike) -> Array:
        """Per-axis standard deviation (px) of the depth of field's blur of points at
        ``distance`` m (zeros when the lens is unknown): :func:`thin_lens_sigma`."""
        d = np.asarray(distance, dtype=np.float64)
        if not self.has_lens:
            return np.zeros_like(d)
        return thin_lens_sigma(self.fx, self.focal_length, self.f_number, self.focus_distance, d)

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0.0))

    @staticmethod
    def from_focal(
        width: int, height: int, focal_length: float, pixel_size: float, name: str = 'camera'
    ) -> CameraModel:
        """An ideal camera from a lens focal length and a pixel pitch (both in metres)."""
        f = focal_length / pixel_size
        K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0, 0, 1]])
        return CameraModel(width, height, K, np.zeros(5), name)

    def project(self, points: ArrayLike) -> Array:
        """Project camera-frame points (N, 3) to pixels (N, 2), with distortion."""
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        xn = p[:, :2] / p[:, 2:3]
        if self.has_distortion:
            xn = self._distort(xn)
        return np.asarray(xn * [self.fx, self.fy] + [self.cx, self.cy], dtype=np.float64)

    def rays(self, pixels: ArrayLike) -> Array:
        """Unit-z rays (N, 3) in the camera frame through pixels (N, 2), undoing distortion."""
        px = np.atleast_2d(np.asarray(pixels, dtype=np.float64))
        xn = (px - [self.cx, self.cy]) / [self.fx, self.fy]
        if self.has_distortion:
            xn = self.undistort_normalized(xn)
        return np.column_stack([xn, np.ones(len(xn))])

    def undistort_pixels(self, pixels: ArrayLike) -> Array:
        """Pixels of an ideal (distortion-free) camera with the same K."""
        if not self.has_distortion:
            return np.atleast_2d(np.asarray(pixels, dtype=np.float64)).copy()
        r = self.rays(pixels)
        return np.asarray(r[:, :2] * [self.fx, self.fy] + [self.cx, self.cy], dtype=np.float64)

    def _distort(self, xn: Array) -> Array:
        k1, k2, p1, p2, k3 = self.dist[:5]
        x, y = xn[:, 0], xn[:, 1]
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.column_stack([xd, yd])

    def undistort_normalized(self, xd: Array, iterations: int = 20) -> Array:
        """Invert the distortion model by fixed-point iteration (as cv2.undistortPoints), at
        most ``iterations`` passes, stopping once no point moves by 1e-12 (normalised units,
        ~1e-9 px)."""
        k1, k2, p1, p2, k3 = (float(c) for c in self.dist[:5])
        x0, y0 = xd[:, 0], xd[:, 1]
        u, v = x0.copy(), y0.copy()
        for _ in range(iterations):
            r2 = u * u + v * v
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            uv = u * v
            nu = (x0 - (2 * p1 * uv + p2 * (r2 + 2 * u * u))) / radial
            nv = (y0 - (p1 * (r2 + 2 * v * v) + 2 * p2 * uv)) / radial
            moved = max(
                float(np.max(np.abs(nu - u), initial=0.0)),
                float(np.max(np.abs(nv - v), initial=0.0)),
            )
            u, v = nu, nv
            if moved < 1e-12:
                break
        return np.column_stack([u, v])

    # -- YAML (ROS camera_calibration layout) -----------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            'camera_name': self.name,
            'image_width': self.width,
            'image_height': self.height,
            'camera_matrix': {'rows': 3, 'cols': 3, 'data': self.K.reshape(-1).tolist()},
            'distortion_model': 'plumb_bob',
            'distortion_coefficients': {'rows': 1, 'cols': 5, 'data': self.dist.tolist()},
            # A monocular camera as camera_calibration writes it: no rectification, P = [K | 0]
            # (camera_calibration_parsers reads both unconditionally).
            'rectification_matrix': {'rows': 3, 'cols': 3, 'data': np.eye(3).reshape(-1).tolist()},
            'projection_matrix': {
                'rows': 3,
                'cols': 4,
                'data': np.hstack([self.K, np.zeros((3, 1))]).reshape(-1).tolist(),
            },
            # Ours, beside the camera_calibration keys (their readers ignore them); only when
            # not the defaults, so that a linear camera's file is camera_calibration's own.
            **({'response': {'gamma': float(self.gamma)}} if self.gamma != 1.0 else {}),
            **({'exposure_time': float(self.exposure_time)} if self.exposure_time else {}),
            **(
                {
                    'lens': {
                        'f_number': float(self.f_number),
                        'focus_distance': float(self.focus_distance),
                        'focal_length': float(self.focal_length),
                    }
                }
                if self.has_lens
                else {}
            ),
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> CameraModel:
        """Read the ROS camera_calibration layout.

        Raises:
            CalibrationError: with the missing or malformed key.
        """
        try:
            K = np.array(data['camera_matrix']['data'], dtype=np.float64).reshape(3, 3)
            dist = np.array(
                data.get('distortion_coefficients', {}).get('data', [0.0] * 5), dtype=np.float64
            )
            return CameraModel(
                int(data['image_width']),
                int(data['image_height']),
                K,
                dist,
                str(data.get('camera_name', 'camera')),
                float((data.get('response') or {}).get('gamma', 1.0)),
                float(data.get('exposure_time', 0.0)),
                *(
                    float((data.get('lens') or {}).get(k, 0.0))
                    for k in ('f_number', 'focus_distance', 'focal_length')
                ),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f'malformed camera calibration: {exc!r}') from exc

    def save(self, path: Path) -> None:
        path.write_text(yaml.safe_dump(self.to_dict(), sort_keys=False))

    @staticmethod
    def load(path: Path | str) -> CameraModel:
        try:
            data = load_yaml(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise CalibrationError(f'cannot read camera calibration {path}: {exc}') from exc
        if not isinstance(data, dict):
            raise CalibrationError(f'{path}: expected a mapping, got {type(data).__name__}')
        return CameraModel.from_dict(data)


# Table I defaults.
DYNAMIC_FOCAL_LENGTH = 25e-3
DYNAMIC_PIXEL_SIZE = 5e-6  # 1/4-inch CMOS, 3.2 mm / 640 px
OVERHEAD_FOCAL_LENGTH = 12e-3
OVERHEAD_PIXEL_SIZE = 10e-6  # assumed 1/2-inch CCD, 6.4 mm / 640 px


def dynamic_camera(name: str = 'cam1') -> CameraModel:
    """The paper's dynamic camera: 640x480, 1/4-inch CMOS, 25 mm lens."""
    return CameraModel.from_focal(640, 480, DYNAMIC_FOCAL_LENGTH, DYNAMIC_PIXEL_SIZE, name)


def overhead_camera(name: str = 'overhead') -> CameraModel:
    """The paper's static overhead camera: 640x480 CCD, 12 mm lens."""
    return CameraModel.from_focal(640, 480, OVERHEAD_FOCAL_LENGTH, OVERHEAD_PIXEL_SIZE, name)


def intrinsics_discrepancy(a: CameraModel, b: CameraModel) -> float:
    """How far two calibrations of one camera disagree, in pixels at the image's edge.

    The largest of the principal points' offsets and the focal lengths' difference as it moves
    a point at the image border; infinite for different image sizes.
    """
    if (a.width, a.height) != (b.width, b.height):
        return math.inf
    ka, kb = np.asarray(a.K), np.asarray(b.K)
    return float(
        max(
            abs(ka[0, 2] - kb[0, 2]),
            abs(ka[1, 2] - kb[1, 2]),
            abs(ka[0, 0] - kb[0, 0]) * 0.5 * a.width / ka[0, 0],
            abs(ka[1, 1] - kb[1, 1]) * 0.5 * a.height / ka[1, 1],
        )
    )
