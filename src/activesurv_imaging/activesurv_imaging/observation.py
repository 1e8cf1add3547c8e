"""One camera's answer to a capture request, in the world frame (the imager node's core).

Chains :func:`activesurv_imaging.marker_pose.measure_marker`, the camera pose from the stage
joint states, and the sensor model's covariance at the measured distance and bearing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, bearing, unit
from activesurv_common.sensor_model import SensorModel
from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.ellipse import Ellipse
from activesurv_imaging.errors import VisionErrors
from activesurv_imaging.marker_pose import MarkerMeasurement, MeasurementStatus, measure_marker

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Observation:
    camera_id: str
    demand_index: int
    stamp: float
    status: ObservationStatus
    reason: str = ''
    position: Array | None = None
    normal: Array | None = None
    covariance: Array | None = None
    ellipse: Ellipse | None = None
    chosen: int = 0
    margin: float = 0.0
    distance: float = math.nan
    bearing: float = math.nan
    camera_pose: Transform | None = None
    frame_offset: float = 0.0  # s: exposure instant minus demand instant
    motion_correction: Array | None = None  # m added for the object's motion over the offset
    compute_time: float = 0.0  # s: processing of the frame (detect, fit, pose)
    frame_received: float = math.nan  # s: the frame's arrival minus the demand instant
    streak: Array | None = None  # px the marker's image moved over the exposure (taken out)
    blur: float = 0.0  # px: the view's blur beyond a sharp view's (the sensor model's b)
    demand_time: float = math.nan  # s: the instant it answers (set by CaptureCore.poll)


def failed(
    camera_id: str,
    demand_index: int,
    stamp: float,
    status: ObservationStatus,
    reason: str,
    camera_pose: Transform | None = None,
) -> Observation:
    return Observation(camera_id, demand_index, stamp, status, reason, camera_pose=camera_pose)


NEAR_GATE = 0.015  # m: a marker farther than this from its prediction is another object's
# What the streak's correction leaves unknown, as a fraction of the correction (the velocity
# is a prediction, the exposure a nominal time; measured on rendered streaks: 5-15 %).
STREAK_LEFT = 0.25


def image_streak(
    camera: CameraModel,
    T_world_camera: Transform,
    position_world: ArrayLike | None,
    velocity_world: ArrayLike | None,
    exposure_time: float | None = None,
) -> Array | None:
    """(du, dv) px: how far the marker's image moves over the exposure (``exposure_time``,
    default the camera model's) at its predicted position and velocity; None when either is
    unknown or the marker is behind the camera."""
    t_exp = camera.exposure_time if exposure_time is None else exposure_time
    if position_world is None or velocity_world is None or not (t_exp > 0.0):
        return None
    p = np.asarray(position_world, dtype=np.float64).reshape(3)
    v = np.asarray(velocity_world, dtype=np.float64).reshape(-1)
    if v.shape == (2,):
        v = np.r_[v, 0.0]
    if v.shape != (3,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
        return None
    inv = T_world_camera.inverse()
    ends = np.stack([inv.apply(p - 0.5 * t_exp * v), inv.apply(p + 0.5 * t_exp * v)])
    if np.any(ends[:, 2] <= 1e-6):
        return None
    uv = camera.project(ends)
    out: Array = np.asarray(uv[1] - uv[0], dtype=np.float64)
    return out if np.all(np.isfinite(out)) else None


def _streak_variance(m: MarkerMeasurement, d: float) -> float:
    """m^2 along the line of sight: what is left unknown of the streak's correction (a
    fraction of how far it moved the marker: its apparent size is its distance)."""
    if m.swept is None or m.ellipse is None:
        return 0.0
    a0, b0 = m.swept.semi_axes
    a1, b1 = m.ellipse.semi_axes
    moved = d * abs(1.0 - math.sqrt((a0 * b0) / (a1 * b1)))
    return (STREAK_LEFT * moved) ** 2


def observe_marker(
    image: ArrayLike,
    camera: CameraModel,
    T_world_camera: Transform,
    radius: float,
    model: SensorModel,
    camera_id: str,
    demand_index: int,
    stamp: float,
    prior_normal_world: ArrayLike | None = None,
    wrong_solution: bool = False,
    prior_position_world: ArrayLike | None = None,
    streak: ArrayLike | None = None,
) -> Observation:
    """Measure the marker in ``image`` and express it in the world frame with its covariance.

    ``wrong_solution`` takes the other of the two circle poses (fault injection).
    ``prior_position_world``: where the marker is predicted; of several markers in view
    (several objects), the one nearest its projection is measured. ``streak``: px the
    marker's image moved over the exposure (:func:`image_streak`): taken out of the ellipse,
    and what that leaves unknown added to the covariance along the line of sight.
    """
    prior = None
    if prior_normal_world is not None:
        try:
            prior = T_world_camera.inverse().rotate(unit(prior_normal_world, 'prior normal'))
        except VisionErrors:
            prior = None  # a zero or NaN prior: fall back to the frontal choice
    near, gate = None, None
    if prior_position_world is not None:
        p = T_world_camera.inverse().apply(np.asarray(prior_position_world, dtype=np.float64))
        if np.all(np.isfinite(p)) and p[2] > 1e-6:
            near = camera.project(p[None, :])[0]
            gate = NEAR_GATE * camera.fx / float(p[2])
    try:
        m = measure_marker(image, camera, radius, prior, near=near, near_gate=gate, streak=streak)
    except VisionErrors as exc:
        return failed(
            camera_id,
            demand_index,
            stamp,
            ObservationStatus.REJECTED,
            f'bad image: {exc}',
            T_world_camera,
        )
    if m.status is not MeasurementStatus.OK or m.pose is None:
        return Observation(
            camera_id,
            demand_index,
            stamp,
            ObservationStatus(m.status.value),
            m.reason,
            ellipse=m.ellipse,
            camera_pose=T_world_camera,
        )
    pose = m.poses[1 - m.chosen] if (wrong_solution and m.poses is not None) else m.pose
    c, n = pose.center, pose.normal
    d = float(np.linalg.norm(c))
    theta = bearing(-c, n)  # the camera is at the origin of its frame
    # The view's blur (its edges' and its streak's): a blurred marker is measured less well.
    length = 0.0 if streak is None else float(np.hypot(*np.asarray(streak, dtype=np.float64)))
    blur = model.blur_of(m.blur_sigma, length) if model.models_blur else 0.0
    cov = model.world_covariance(d, theta, T_world_camera.R, blur)
    if m.visible < 1.0:  # fitted to the arc that showed: its size (distance) the less sure
        cov = cov / max(m.visible, 0.1) ** 4
    left = _streak_variance(m, d)
    if left > 0.0:
        ray = T_world_camera.rotate(c / d)
        cov = cov.copy()
        cov[:3, :3] += left * np.outer(ray, ray)  # the position's block
    return Observation(
        camera_id,
        demand_index,
        stamp,
        ObservationStatus.OK,
        '',
        position=T_world_camera.apply(c),
        normal=T_world_camera.rotate(n),
        covariance=cov,
        ellipse=m.ellipse,
        chosen=m.chosen,
        margin=m.margin,
        distance=d,
        bearing=theta,
        camera_pose=T_world_camera,
        streak=None if m.swept is None else np.asarray(streak, dtype=np.float64).reshape(2),
        blur=blur,
    )


def perturb(
    obs: Observation,
    bias_x: float = 0.0,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
) -> Observation:
    """Fault injection: add ``bias_x`` (m, world x) and Gaussian noise (m std) to a position."""
    if obs.position is None or (bias_x == 0.0 and noise <= 0.0):
        return obs
    p = obs.position.copy()
    p[0] += bias_x
    if noise > 0.0:
        p += (rng or np.random.default_rng()).normal(0.0, noise, 3)
    return replace(obs, position=p)
