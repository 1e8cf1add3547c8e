"""A camera's lens and exposure, as the simulator images with them (issue 33, real optics).

Four things a lab camera does to a frame that a pinhole does not:

* **Depth of field** (thin lens). A point at distance ``d`` from a lens of focal length ``f``
  and f-number ``N`` focused at ``d_f`` is a blur circle of diameter
  ``c = (f / N) f |d - d_f| / (d (d_f - f))`` on the sensor; in pixels (pitch ``f / fx``) that is
  ``fx (f / N) |d - d_f| / (d (d_f - f))``. Its per-axis standard deviation, a uniform disc's,
  is ``c / 4``; it adds in quadrature to the lens's own blur.
* **Motion blur.** The shutter is open ``exposure_time``: a marker moving in the image (the
  object on the table, the camera on its stages) is smeared along its image path over it.
* **Exposure.** Grey levels scale with the exposure time (the renders' levels are those of
  :data:`REFERENCE_EXPOSURE`); a short exposure is a dim frame, a long one saturates.
* **Response.** ``grey = 255 (radiance / full scale)^(1 / gamma)``, the convention of
  :class:`activesurv_common.camera_model.CameraModel` ``.gamma`` (1: linear).

Defaults are the paper's (Table I: 25 mm lenses on the dynamic cameras, 12 mm on the overhead
one) at f/4, 10 ms, linear; the focus distance of a nominal rig is where each camera looks at the
middle of the table (:func:`focus_for`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from activesurv_common.camera_model import CameraModel, thin_lens_sigma
from activesurv_common.geometry import Transform
from activesurv_sim.errors import SimError
from activesurv_sim.frame_optics import IDEAL_OPTICS, FrameOptics

REFERENCE_EXPOSURE = 0.010  # s: the exposure the renderer's grey levels stand for
DYNAMIC_FOCAL_LENGTH = 0.025  # m (Table I)
OVERHEAD_FOCAL_LENGTH = 0.012  # m (Table I)
WORKSPACE_CENTRE = (0.25, 0.10, 0.05)  # m: the table's middle at the side marker's height
MAX_STREAK = 128.0  # px: more over one exposure is a jump, not a motion
MAX_DEFOCUS = 12.0  # px: a far point's blur (a 48 px circle: beyond what the imager measures)


class OpticsError(SimError, ValueError):
    """Optics values out of range."""


@dataclass(frozen=True)
class Optics:
    """A camera's lens and exposure (SI).

    Attributes:
        f_number: the aperture's f-number (``f / N`` is its diameter).
        focus_distance: the distance the lens is focused at (m).
        exposure_time: how long the shutter is open (s).
        gamma: the response, ``grey = 255 (radiance / full scale)^(1 / gamma)``.
        focal_length: of the lens (m).
    """

    f_number: float = 4.0
    focus_distance: float = 0.5
    exposure_time: float = REFERENCE_EXPOSURE
    gamma: float = 1.0
    focal_length: float = DYNAMIC_FOCAL_LENGTH

    def __post_init__(self) -> None:
        checks = (
            ('f_number', self.f_number, 0.7, 64.0),
            ('focus_distance', self.focus_distance, 0.05, 100.0),
            ('exposure_time', self.exposure_time, 1e-5, 0.5),
            ('gamma', self.gamma, 0.2, 5.0),
            ('focal_length', self.focal_length, 0.001, 0.5),
        )
        for name, value, low, high in checks:
            if not (math.isfinite(value) and low <= value <= high):
                raise OpticsError(f'optics.{name} must be in {low:g}..{high:g}, got {value!r}')
        if self.focus_distance <= self.focal_length:
            raise OpticsError('optics.focus_distance must exceed the focal length')

    @property
    def gain(self) -> float:
        """Grey levels relative to the renderer's (:data:`REFERENCE_EXPOSURE`)."""
        return self.exposure_time / REFERENCE_EXPOSURE

    def defocus_sigma(self, fx: float, distance: float) -> float:
        """Per-axis standard deviation (px) of the blur circle of a point ``distance`` m from
        the lens, for a camera of ``fx`` px focal length."""
        return float(
            thin_lens_sigma(fx, self.focal_length, self.f_number, self.focus_distance, distance)
        )

    def depth_of_field(self, fx: float, max_sigma: float = 1.0) -> tuple[float, float]:
        """The distances (m) between which the defocus blur stays within ``max_sigma`` px."""
        f, df = self.focal_length, self.focus_distance
        k = 4.0 * max_sigma * (df - f) / (fx * f / self.f_number)  # |d - df| / d <= k
        near = df / (1.0 + k)
        far = df / (1.0 - k) if k < 1.0 else math.inf
        return near, far

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    @staticmethod
    def from_dict(data: dict[str, Any] | None, default: Optics) -> Optics:
        """``data`` over ``default`` (keys left out keep the default's values).

        Raises:
            OpticsError: for a value out of range.
        """
        if not data:
            return default
        given = {k: float(v) for k, v in data.items() if v is not None}
        return Optics(**{**default.to_dict(), **given})


def frame_optics(
    camera: CameraModel,
    optics: Optics | None,
    pose: Transform,
    marker: ArrayLike,
    ends: tuple[tuple[Transform, ArrayLike], tuple[Transform, ArrayLike]] | None = None,
) -> FrameOptics:
    """What ``optics`` do to a frame of ``marker`` (world point, m) seen from ``pose``: the
    depth of field's blur at its distance and, given the camera pose and marker position at
    the exposure's start and end (``ends``), the marker's streak across the image."""
    if optics is None:
        return IDEAL_OPTICS
    p = np.asarray(marker, dtype=np.float64).reshape(3)
    sigma = optics.defocus_sigma(camera.fx, float(np.linalg.norm(p - pose.t)))
    streak = (0.0, 0.0)
    if ends is not None:
        (Ta, pa), (Tb, pb) = ends
        ua = camera.project(Ta.inverse().apply(pa))[0]
        ub = camera.project(Tb.inverse().apply(pb))[0]
        du, dv = (float(v) for v in ub - ua)
        # A marker that jumped (entering, parked) or passed behind the lens leaves no streak.
        if math.isfinite(du) and math.isfinite(dv) and math.hypot(du, dv) <= MAX_STREAK:
            streak = (du, dv)
    return FrameOptics(min(sigma, MAX_DEFOCUS), streak, optics.gain, optics.gamma)


def focus_for(camera_position: ArrayLike, focal_length: float = DYNAMIC_FOCAL_LENGTH) -> Optics:
    """The paper's optics (f/4, 10 ms, linear) focused at the middle of the table as seen from
    ``camera_position`` (a camera's mount base, world frame, m)."""
    p = np.asarray(camera_position, dtype=np.float64).reshape(3)
    d = float(np.linalg.norm(p - np.asarray(WORKSPACE_CENTRE)))
    return Optics(focus_distance=round(max(d, 2.0 * focal_length), 4), focal_length=focal_length)
