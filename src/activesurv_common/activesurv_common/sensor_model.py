"""Sensor model of a dynamic camera (paper Appendix A).

The variances of the six measured quantities (x, y, z, n_x, n_y, n_z) depend, of the controllable
parameters, only on the camera-to-target distance d and the bearing theta (the angle between the
marker normal and the line of sight). Each variance is a response surface fitted by the
two-factorial experiment (:mod:`activesurv_studies.sensor_model_experiment`)::

    log(sigma^2) = c0 + c1 d + c2 theta + c3 d^2 + c4 d theta + c5 theta^2
                   + c6 log(theta + theta0),   theta0 = 3 deg

Fitting the logarithm keeps variances positive. The quadratic is the usual response surface;
the last term is ours: seen face-on the marker's image is nearly a circle whose orientation, and
so the normal, is poorly determined, and the normal variances rise like 1/theta^2 towards
theta = 0, which no quadratic follows (the fit was off by two orders of magnitude there).

Variances are measured in the camera optical frame (x, y across the image, z along the line of
sight), where they separate cleanly. The world covariance rotates the position and normal
blocks: ``R_world = blkdiag(Rc S_pos Rc^T, Rc S_n Rc^T)``. The Frobenius norm, and so the
visibility ``1 / ||R||``, is the same in both frames. Units are SI: m^2 for positions and the
square of a unit-vector component for the normal.

Outside the fitted (d, theta) ranges the surfaces are evaluated at the nearest point of the
range (no extrapolation). Bearings beyond ``max_bearing``, or a marker outside the image, make
the camera blind to the target: :func:`view_geometry` says so and the visibility is 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.errors import SensorModelError
from activesurv_common.geometry import Transform, as_vector3, unit
from activesurv_common.geometry import bearing as geometry_bearing

Array = NDArray[np.float64]
VARIABLES = ('x', 'y', 'z', 'n_x', 'n_y', 'n_z')


THETA0 = math.radians(3.0)
N_TERMS = 7


def design_row(d: float, theta: float) -> Array:
    """The response-surface basis (1, d, theta, d^2, d theta, theta^2, log(theta + theta0))."""
    return np.array([1.0, d, theta, d * d, d * theta, theta * theta, math.log(theta + THETA0)])


@dataclass(frozen=True)
class SensorModel:
    """Variance response surfaces of one camera type.

    Attributes:
        coefficients: (6 variables, 7 basis terms) coefficients of log variance.
        d_range: (min, max) distance covered by the experiment (m).
        theta_range: (min, max) bearing covered by the experiment (rad).
        max_bearing: bearing beyond which the marker is not measurable (rad).
        samples: optional raw experiment data, kept for plots and reports.
    """

    coefficients: Array
    d_range: tuple[float, float]
    theta_range: tuple[float, float]
    max_bearing: float = math.radians(75.0)
    samples: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        c = np.asarray(self.coefficients, dtype=np.float64)
        if c.shape != (6, N_TERMS) or not np.all(np.isfinite(c)):
            raise SensorModelError(
                f'coefficients must be a finite 6x{N_TERMS} array, got {c.shape}'
            )
        object.__setattr__(self, 'coefficients', c)
        (d0, d1), (t0, t1) = self.d_range, self.theta_range
        if not (0.0 < d0 < d1 and 0.0 <= t0 < t1 <= math.pi / 2):
            raise SensorModelError(f'invalid ranges d={self.d_range} theta={self.theta_range}')
        if not 0.0 < self.max_bearing < math.pi / 2:
            raise SensorModelError('max_bearing must be in (0, pi/2)')

    def variances(self, d: float, theta: float) -> Array:
        """The six variances (camera frame) at distance ``d`` and bearing ``theta``.

        Raises:
            SensorModelError: for non-finite or negative arguments.
        """
        if not (math.isfinite(d) and math.isfinite(theta)) or d <= 0.0 or theta < 0.0:
            raise SensorModelError(f'need finite d > 0 and theta >= 0, got d={d}, theta={theta}')
        dc = min(max(d, self.d_range[0]), self.d_range[1])
        tc = min(max(theta, self.theta_range[0]), self.theta_range[1])
        return np.asarray(np.exp(self.coefficients @ design_row(dc, tc)), dtype=np.float64)

    def variances_batch(self, d: ArrayLike, theta: ArrayLike) -> Array:
        """Vectorised :meth:`variances`: (N,) distances and bearings -> (N, 6) variances."""
        dc = np.clip(np.asarray(d, dtype=np.float64), *self.d_range)
        tc = np.clip(np.asarray(theta, dtype=np.float64), *self.theta_range)
        basis = np.stack(
            [np.ones_like(dc), dc, tc, dc * dc, dc * tc, tc * tc, np.log(tc + THETA0)], axis=-1
        )
        return np.asarray(np.exp(basis @ self.coefficients.T), dtype=np.float64)

    def covariance(self, d: float, theta: float) -> Array:
        """6x6 diagonal covariance in the camera optical frame."""
        return np.diag(self.variances(d, theta))

    def world_covariance(self, d: float, theta: float, R_world_camera: ArrayLike) -> Array:
        """6x6 covariance over (x, y, z, n_x, n_y, n_z) in the world frame."""
        R = np.asarray(R_world_camera, dtype=np.float64)
        v = self.variances(d, theta)
        out = np.zeros((6, 6))
        out[:3, :3] = R @ np.diag(v[:3]) @ R.T
        out[3:, 3:] = R @ np.diag(v[3:]) @ R.T
        return out

    # -- YAML ------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            'sensor_model': {
                'description': 'log(variance) = c . [1, d, theta, d^2, d*theta, theta^2, '
                'log(theta + 3 deg)]; variances in the camera optical frame, '
                'm^2 and (unit normal)^2; d in m, theta in rad',
                'variables': list(VARIABLES),
                'frame': 'camera_optical',
                'd_range': [float(v) for v in self.d_range],
                'theta_range': [float(v) for v in self.theta_range],
                'max_bearing': float(self.max_bearing),
                'log_variance_coefficients': {
                    name: [float(v) for v in row]
                    for name, row in zip(VARIABLES, self.coefficients, strict=True)
                },
                'samples': self.samples,
            }
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> SensorModel:
        try:
            m = data['sensor_model']
            coeffs = np.array([m['log_variance_coefficients'][v] for v in VARIABLES], dtype=float)
            return SensorModel(
                coeffs,
                tuple(m['d_range']),
                tuple(m['theta_range']),
                float(m.get('max_bearing', math.radians(75.0))),
                dict(m.get('samples') or {}),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise SensorModelError(f'malformed sensor model: {exc!r}') from exc

    def save(self, path: Path) -> None:
        Path(path).write_text(yaml.safe_dump(self.to_dict(), sort_keys=False))

    @staticmethod
    def load(path: Path | str | None = None) -> SensorModel:
        """Load a sensor model YAML; ``None`` loads the one shipped with the package."""
        p = default_model_path() if path is None else Path(path)
        try:
            data = yaml.safe_load(p.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise SensorModelError(f'cannot read sensor model {p}: {exc}') from exc
        if not isinstance(data, dict):
            raise SensorModelError(f'{p}: expected a mapping')
        return SensorModel.from_dict(data)


def default_model_path() -> Path:
    """The sensor model measured for the default dynamic camera (shipped as package data)."""
    return Path(__file__).resolve().parent / 'data' / 'sensor_model.yaml'


@dataclass(frozen=True)
class ViewGeometry:
    """How a camera sees the marker.

    Attributes:
        distance: camera-to-marker distance d (m).
        bearing: angle theta between the marker normal and the line of sight (rad).
        in_view: the whole marker projects inside the image (with margin) and faces the camera
            at a measurable bearing.
        pixel: the marker centre's image position (pixels).
    """

    distance: float
    bearing: float
    in_view: bool
    pixel: Array


def view_geometry(
    camera: CameraModel,
    T_world_camera: Transform,
    center: ArrayLike,
    normal: ArrayLike,
    radius: float,
    max_bearing: float = math.radians(75.0),
    margin_px: float = 4.0,
) -> ViewGeometry:
    """Distance, bearing and visibility of a marker for a camera pose."""
    c = as_vector3(center, 'center')
    n = unit(normal, 'normal')
    to_cam = T_world_camera.t - c
    d = float(np.linalg.norm(to_cam))
    if d < 1e-9:
        return ViewGeometry(0.0, math.pi, False, np.array([np.nan, np.nan]))
    bearing = geometry_bearing(to_cam, n)
    p_cam = T_world_camera.inverse().apply(c)
    if p_cam[2] <= radius:
        return ViewGeometry(d, bearing, False, np.array([np.nan, np.nan]))
    px = camera.project(p_cam[None, :])[0]
    # Conservative image radius of the marker: its radius seen frontally at its depth.
    r_px = camera.fx * radius / p_cam[2]
    inside = (
        margin_px + r_px <= px[0] <= camera.width - 1 - margin_px - r_px
        and margin_px + r_px <= px[1] <= camera.height - 1 - margin_px - r_px
    )
    return ViewGeometry(d, bearing, bool(inside and bearing < max_bearing), px)
