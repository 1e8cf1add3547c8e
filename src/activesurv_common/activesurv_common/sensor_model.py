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

**Blur** (issue 33: real optics) is a third factor beside d and theta: the marker's image blur
``b`` (px, per-axis standard deviation of the isotropic blur: the depth of field's, plus a motion
streak's ``L / sqrt(12)`` in quadrature) multiplies each variance by ``(1 + (b / B0)^2)^cb``
(``B0`` = 1 px, ``cb`` per variable, :attr:`SensorModel.blur_coefficients`; zero in a model
measured without optics, which then says what it always said). ``b`` is evaluated up to
:data:`MAX_BLUR` (beyond, the marker is not measured reliably at all).

Outside the fitted (d, theta) ranges the surfaces are evaluated at the nearest point of the
range (no extrapolation). Bearings beyond ``max_bearing``, or a marker outside the image, make
the camera blind to the target: :func:`view_geometry` says so and the visibility is 0.
"""

from __future__ import annotations

import math
import os
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
from activesurv_common.yamlio import load_yaml

Array = NDArray[np.float64]
VARIABLES = ('x', 'y', 'z', 'n_x', 'n_y', 'n_z')


THETA0 = math.radians(3.0)
N_TERMS = 7
B0 = 1.0  # px: the blur at which the blur factor is 2^cb
MAX_BLUR = 12.0  # px


def blur_term(blur: ArrayLike) -> Array:
    """``log(1 + (b / B0)^2)`` of the blur ``b`` (px, clipped to [0, MAX_BLUR])."""
    b = np.clip(np.nan_to_num(np.asarray(blur, dtype=np.float64), nan=0.0), 0.0, MAX_BLUR)
    return np.asarray(np.log1p((b / B0) ** 2), dtype=np.float64)


def image_blur(defocus: ArrayLike, streak: ArrayLike = 0.0) -> Array:
    """The isotropic blur (px) a defocus (px, std) and a streak (px, length) amount to: the
    streak's uniform smear has the standard deviation ``L / sqrt(12)``."""
    d = np.asarray(defocus, dtype=np.float64)
    s = np.asarray(streak, dtype=np.float64)
    return np.asarray(np.sqrt(d * d + s * s / 12.0), dtype=np.float64)


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
        blur_coefficients: (6,) ``cb`` of the blur factor (zeros: blur not modelled).
        blur_base: px, the blur a sharp view's edges show (the lens's own and the pixel's:
            what the d-theta surfaces already hold); a measured edge blur beyond it is ``b``
            (:meth:`blur_of`).
    """

    coefficients: Array
    d_range: tuple[float, float]
    theta_range: tuple[float, float]
    max_bearing: float = math.radians(75.0)
    samples: dict[str, Any] = field(default_factory=dict)
    blur_coefficients: Array = field(default_factory=lambda: np.zeros(6))
    blur_base: float = 0.0

    def __post_init__(self) -> None:
        c = np.asarray(self.coefficients, dtype=np.float64)
        if c.shape != (6, N_TERMS) or not np.all(np.isfinite(c)):
            raise SensorModelError(
                f'coefficients must be a finite 6x{N_TERMS} array, got {c.shape}'
            )
        object.__setattr__(self, 'coefficients', c)
        cb = np.asarray(self.blur_coefficients, dtype=np.float64).reshape(-1)
        if cb.shape != (6,) or not np.all(np.isfinite(cb)) or np.any(cb < 0.0):
            raise SensorModelError(f'blur_coefficients must be 6 finite values >= 0, got {cb}')
        object.__setattr__(self, 'blur_coefficients', cb)
        # Asked on every view the planner weighs: kept, not recomputed (the model is frozen).
        object.__setattr__(self, '_models_blur', bool(np.any(cb > 0.0)))
        (d0, d1), (t0, t1) = self.d_range, self.theta_range
        if not (0.0 < d0 < d1 and 0.0 <= t0 < t1 <= math.pi / 2):
            raise SensorModelError(f'invalid ranges d={self.d_range} theta={self.theta_range}')
        if not 0.0 < self.max_bearing < math.pi / 2:
            raise SensorModelError('max_bearing must be in (0, pi/2)')

    def blur_of(self, edge_blur: float, streak: float = 0.0) -> float:
        """``b`` (px) of a view whose edges showed ``edge_blur`` px (the detector's isotropic
        estimate) and whose marker streaked ``streak`` px over the exposure."""
        e = float(edge_blur) if math.isfinite(edge_blur) else 0.0
        extra = math.sqrt(max(e * e - self.blur_base**2, 0.0))
        return float(image_blur(extra, float(streak) if math.isfinite(streak) else 0.0))

    @property
    def models_blur(self) -> bool:
        """Whether blur changes the variances (a model measured with optics)."""
        return bool(self.__dict__['_models_blur'])

    def variances(self, d: float, theta: float, blur: float = 0.0) -> Array:
        """The six variances (camera frame) at distance ``d``, bearing ``theta`` and image
        blur ``blur`` (px: :func:`image_blur`).

        Raises:
            SensorModelError: for non-finite or negative arguments.
        """
        if not (math.isfinite(d) and math.isfinite(theta)) or d <= 0.0 or theta < 0.0:
            raise SensorModelError(f'need finite d > 0 and theta >= 0, got d={d}, theta={theta}')
        dc = min(max(d, self.d_range[0]), self.d_range[1])
        tc = min(max(theta, self.theta_range[0]), self.theta_range[1])
        log_v = self.coefficients @ design_row(dc, tc)
        if blur:
            log_v = log_v + self.blur_coefficients * float(blur_term(blur))
        return np.asarray(np.exp(log_v), dtype=np.float64)

    def variances_batch(
        self, d: ArrayLike, theta: ArrayLike, blur: ArrayLike | None = None
    ) -> Array:
        """Vectorised :meth:`variances`: (N,) distances, bearings (and blurs, px) -> (N, 6)
        variances."""
        dc = np.clip(np.asarray(d, dtype=np.float64), *self.d_range)
        tc = np.clip(np.asarray(theta, dtype=np.float64), *self.theta_range)
        basis = np.stack(
            [np.ones_like(dc), dc, tc, dc * dc, dc * tc, tc * tc, np.log(tc + THETA0)], axis=-1
        )
        log_v = basis @ self.coefficients.T
        if blur is not None and self.models_blur:
            log_v = log_v + blur_term(blur)[..., None] * self.blur_coefficients
        return np.asarray(np.exp(log_v), dtype=np.float64)

    def covariance(self, d: float, theta: float, blur: float = 0.0) -> Array:
        """6x6 diagonal covariance in the camera optical frame."""
        return np.diag(self.variances(d, theta, blur))

    def world_covariance(
        self, d: float, theta: float, R_world_camera: ArrayLike, blur: float = 0.0
    ) -> Array:
        """6x6 covariance over (x, y, z, n_x, n_y, n_z) in the world frame."""
        R = np.asarray(R_world_camera, dtype=np.float64)
        v = self.variances(d, theta, blur)
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
                **(
                    {
                        'blur_description': 'variance x (1 + (b / 1 px)^2)^cb; b: image blur '
                        '(px std: defocus, streak length / sqrt 12)',
                        'blur_coefficients': {
                            name: float(v)
                            for name, v in zip(VARIABLES, self.blur_coefficients, strict=True)
                        },
                        'blur_base': float(self.blur_base),
                    }
                    if self.models_blur
                    else {}
                ),
                'samples': self.samples,
            }
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> SensorModel:
        try:
            m = data['sensor_model']
            coeffs = np.array([m['log_variance_coefficients'][v] for v in VARIABLES], dtype=float)
            blur = m.get('blur_coefficients') or {}
            return SensorModel(
                coeffs,
                tuple(m['d_range']),
                tuple(m['theta_range']),
                float(m.get('max_bearing', math.radians(75.0))),
                dict(m.get('samples') or {}),
                np.array([float(blur.get(v, 0.0)) for v in VARIABLES]),
                float(m.get('blur_base', 0.0)),
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
            data = load_yaml(p.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise SensorModelError(f'cannot read sensor model {p}: {exc}') from exc
        if not isinstance(data, dict):
            raise SensorModelError(f'{p}: expected a mapping')
        return SensorModel.from_dict(data)


def default_model_path() -> Path:
    """The sensor model measured for the default dynamic camera (shipped as package data), or
    the file ``ACTIVESURV_SENSOR_MODEL`` names (a study's switch: every node of a run that
    inherits the environment then loads that model, e.g. one without the blur factor)."""
    chosen = os.environ.get('ACTIVESURV_SENSOR_MODEL', '')
    if chosen:
        return Path(chosen)
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
