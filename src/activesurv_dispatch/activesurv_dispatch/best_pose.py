"""Best achievable pose of a camera for a demand point (paper Section II-B, III-C-1).

The best achievable pose is the stage configuration, reachable from the current one in the time
left before the demand instant, that maximises the camera's visibility of the predicted target.
The visibility depends only on the distance d and the bearing theta (Appendix A), provided the
marker is in view. So for any linear position the best yaw is the one that centres the marker,
clipped to what the rotary stage can reach. The heuristic search is then over the linear axis:
a coarse grid of the reachable interval, evaluated in one vectorised batch, then a finer grid
around the best sample. A rotary-only camera has a single candidate.

Reachability: from the current position, an axis can reach ``reachable_distance(dt)`` in either
direction (trapezoidal profile from rest, the same kinematics as the stages), clipped to the
soft limits.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.geometry import bearings
from activesurv_common.occlusion import Obstacle, blocked, inflate
from activesurv_common.sensor_model import SensorModel, image_blur
from activesurv_dispatch.sensors import Sensor
from activesurv_dispatch.visibility import fused_visibility, visibility_from_variances
from activesurv_stages.kinematics import reachable_distance

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Target:
    """A predicted demand point: marker centre, unit normal (world), and position uncertainty.

    ``sigma`` (m) widens the in-view margin: a camera must keep the marker in view even if the
    target is ``VIEW_SIGMAS`` standard deviations off its prediction.
    """

    position: Array
    normal: Array
    sigma: float = 0.0
    velocity: Array | None = None  # m/s at the instant: the streak a view would see


VIEW_SIGMAS = 2.0


def predicted_blur(
    sensor: Sensor, target: Target, rel: Array, d: Array, model: SensorModel
) -> Array | None:
    """The image blur (px, the sensor model's ``b``) each camera at ``rel = target - centre``
    (N, 3), ``d`` away, would see: the depth of field's at that distance (the calibration's lens
    settings) and the streak of the target's motion across the line of sight over the exposure;
    None when the model does not weigh blur."""
    if not model.models_blur:
        return None
    cam = sensor.camera
    defocus = cam.defocus_sigma(d)
    streak = np.zeros_like(d)
    if target.velocity is not None and cam.exposure_time > 0.0:
        v = np.asarray(target.velocity, dtype=np.float64).reshape(-1)
        v = np.r_[v, 0.0] if v.shape == (2,) else v
        ray = rel / np.maximum(d, 1e-9)[:, None]
        across = v[None, :] - (ray @ v)[:, None] * ray
        streak = cam.fx * np.linalg.norm(across, axis=1) * cam.exposure_time / np.maximum(d, 1e-9)
    return image_blur(defocus, streak)


@dataclass(frozen=True)
class Candidate:
    """A camera configuration and how well it sees the target."""

    joints: Array
    visibility: float
    distance: float
    bearing: float
    in_view: bool


def camera_frames(sensor: Sensor, q: Array) -> tuple[Array, Array]:
    """Camera centres (N, 3) and rotations (N, 3, 3) for joint vectors ``q`` (N, J): the
    mount's one kinematics, batched (:meth:`CameraMount.poses_from_joints`)."""
    return sensor.mount.poses_from_joints(q)


def view_batch(
    sensor: Sensor,
    q: Array,
    target: Target,
    radius: float,
    model: SensorModel,
    margin_px: float = 8.0,
    occluders: Sequence[Obstacle] = (),
) -> tuple[Array, Array, Array, Array]:
    """(visibility, distance, bearing, in_view) for each joint vector in ``q`` (N, J).

    With ``occluders``, a camera whose line of sight to the marker passes within the marker's
    radius (plus the prediction's margin) of one is not in view: eq. 1's occluded case.
    """
    (vis, inside), d, bearing = _views(
        sensor, q, target, radius, model, margin_px, occluders, (target.sigma,)
    )
    return vis[0], d, bearing, inside[0]


@dataclass(frozen=True)
class SingleView:
    """One camera pose's view of a target (:func:`view_one`): what :func:`view_batch` gives
    for it, and the pose's rotation and predicted blur that its covariance needs."""

    visibility: float
    distance: float
    bearing: float
    in_view: bool
    R: Array  # (3, 3) world <- camera
    blur_px: float  # the predicted image blur (0 when the model does not weigh it)


def view_one(
    sensor: Sensor,
    q: ArrayLike,
    target: Target,
    radius: float,
    model: SensorModel,
    occluders: Sequence[Obstacle] = (),
) -> SingleView:
    """:func:`view_batch` of one joint vector, with its geometry kept (the same arithmetic)."""
    qq = np.asarray(q, dtype=np.float64)[None, :]
    extra: dict[str, Array | None] = {}
    (vis, inside), d, b = _views(
        sensor, qq, target, radius, model, 8.0, occluders, (target.sigma,), extra
    )
    blur = extra['blur']
    R = extra['R']
    assert R is not None
    return SingleView(
        float(vis[0][0]),
        float(d[0]),
        float(b[0]),
        bool(inside[0][0]),
        R[0],
        0.0 if blur is None else float(blur[0]),
    )


def _views(
    sensor: Sensor,
    q: Array,
    target: Target,
    radius: float,
    model: SensorModel,
    margin_px: float,
    occluders: Sequence[Obstacle],
    sigmas: Sequence[float],
    extra: dict[str, Array | None] | None = None,
) -> tuple[tuple[list[Array], list[Array]], Array, Array]:
    """:func:`view_batch` for the target's position uncertainty taken as each of ``sigmas``
    (only the in-view margins differ: the views' geometry and variances are computed once).
    Returns ((visibility per sigma, in_view per sigma), distance, bearing); ``extra``, when
    given, receives the poses' rotations (``R``) and predicted blur (``blur``)."""
    centres, R = camera_frames(sensor, q)
    rel = target.position[None, :] - centres
    d = np.linalg.norm(rel, axis=1)
    p = np.einsum('nji,nj->ni', R, rel)  # marker centre in each camera frame
    bearing = bearings(-rel, target.normal)
    cam = sensor.camera
    z = np.maximum(p[:, 2], 1e-9)
    u = cam.fx * p[:, 0] / z + cam.cx
    v = cam.fy * p[:, 1] / z + cam.cy
    seen = (p[:, 2] > radius) & (bearing < model.max_bearing)
    blur = predicted_blur(sensor, target, rel, d, model)
    if extra is not None:
        extra['R'], extra['blur'] = R, blur
    vis = visibility_from_variances(model.variances_batch(d, bearing, blur))
    out_vis, out_in = [], []
    for sigma in sigmas:
        r_px = cam.fx * (radius + VIEW_SIGMAS * sigma) / z + margin_px
        in_view = (
            seen
            & (u - r_px >= 0)
            & (u + r_px <= cam.width - 1)
            & (v - r_px >= 0)
            & (v + r_px <= cam.height - 1)
        )
        if occluders:
            grown = inflate(occluders, radius + VIEW_SIGMAS * sigma)
            in_view &= ~blocked(centres, target.position, grown)
        out_vis.append(np.where(in_view, vis, 0.0))
        out_in.append(in_view)
    return (out_vis, out_in), d, bearing


def blur_loss(
    sensor: Sensor, q: ArrayLike, target: Target, radius: float, model: SensorModel
) -> float:
    """The share (0..1) of a camera's visibility at joints ``q`` that its predicted blur (depth
    of field, the target's streak) costs: why a view lost to a sharper one. 0 when the model
    does not weigh blur or the camera does not see the target."""
    if not model.models_blur:
        return 0.0
    qq = np.asarray(q, dtype=np.float64).reshape(1, -1)
    vis, d, b, inside = view_batch(sensor, qq, target, radius, model)
    if not inside[0] or vis[0] <= 0.0:
        return 0.0
    sharp = float(visibility_from_variances(model.variances_batch(d, b))[0])
    return max(0.0, 1.0 - float(vis[0]) / sharp) if sharp > 0.0 else 0.0


def aim_yaw(sensor: Sensor, linear: Array, target: Target) -> Array:
    """Rotary positions that point the optical axis at the target, for each linear position.

    Two fixed-point steps account for the camera centre's offset from the rotation axis.
    """
    m = sensor.mount
    axis = m.linear_axis if m.linear_axis is not None else np.zeros(3)
    pivot = m.base[None, :] + np.atleast_1d(linear)[:, None] * axis[None, :]
    # Direction of the optical axis in the platform frame (pitch only tilts it).
    fwd = m.R_platform_camera[:, 2]
    fwd_angle = math.atan2(fwd[1], fwd[0])
    yaw = np.arctan2(target.position[1] - pivot[:, 1], target.position[0] - pivot[:, 0])
    ox, oy = m.offset[0], m.offset[1]
    for _ in range(2):
        c, s = np.cos(yaw), np.sin(yaw)
        centre = pivot + np.column_stack([c * ox - s * oy, s * ox + c * oy, np.zeros_like(c)])
        yaw = np.arctan2(target.position[1] - centre[:, 1], target.position[0] - centre[:, 0])
    out = yaw - fwd_angle - m.yaw_offset
    return np.asarray((out + np.pi) % (2 * np.pi) - np.pi, dtype=np.float64)


def reachable_box(sensor: Sensor, current: Array, dt: float) -> tuple[Array, Array]:
    """Per-joint (low, high) reachable within ``dt`` seconds, inside the soft limits."""
    lo, hi = [], []
    for q, lim in zip(current, sensor.limits, strict=True):
        r = reachable_distance(dt, lim.max_velocity, lim.max_acceleration) if sensor.moves else 0.0
        lo.append(max(lim.min_position, min(q - r, lim.max_position)))
        hi.append(min(lim.max_position, max(q + r, lim.min_position)))
    return np.array(lo), np.array(hi)


def best_achievable_pose(
    sensor: Sensor,
    current: ArrayLike,
    target: Target,
    dt: float,
    model: SensorModel,
    radius: float,
    samples: int = 21,
    occluders: Sequence[Obstacle] = (),
) -> Candidate:
    """The reachable configuration with the highest visibility of ``target`` in ``dt`` seconds.

    A static camera (or ``dt <= 0``) can only stay where it is. A pose whose line of sight
    ``occluders`` block sees nothing (:func:`view_batch`). When no pose keeps the whole
    uncertainty region (``target.sigma``) in view, the best that keeps the prediction itself in
    view; when none does, the configuration nearest the current one.
    """
    q0 = np.asarray(current, dtype=np.float64)
    lo, hi = reachable_box(sensor, q0, max(dt, 0.0))
    if sensor.has_linear:
        s = np.unique(np.concatenate([np.linspace(lo[0], hi[0], samples), [q0[0]]]))
    else:
        s = np.zeros(1)

    def candidates(lin: Array) -> Array:
        yaw = np.clip(aim_yaw(sensor, lin, target), lo[-1], hi[-1])
        return np.column_stack([lin, yaw]) if sensor.has_linear else yaw[:, None]

    q = candidates(s)
    # The coarse grid's views for the uncertainty region and, should nothing keep it in view,
    # for the prediction alone: the same poses and geometry, two in-view margins.
    sigmas = (target.sigma, 0.0) if target.sigma > 0.0 else (0.0,)
    (coarse, _), d, b = _views(sensor, q, target, radius, model, 8.0, occluders, sigmas)
    for sigma, vis in zip(sigmas, coarse, strict=True):
        aimed = Target(target.position, target.normal, sigma, target.velocity)
        best = int(np.argmax(vis))
        if sensor.has_linear and len(s) > 2 and hi[0] > lo[0]:
            step = (hi[0] - lo[0]) / (samples - 1)
            fine = np.clip(np.linspace(q[best, 0] - step, q[best, 0] + step, 11), lo[0], hi[0])
            qf = candidates(fine)
            vf, df, bf, inf = view_batch(sensor, qf, aimed, radius, model, occluders=occluders)
            j = int(np.argmax(vf))
            if vf[j] > vis[best]:
                return Candidate(qf[j], float(vf[j]), float(df[j]), float(bf[j]), bool(inf[j]))
        if vis[best] > 0.0:
            return Candidate(q[best], float(vis[best]), float(d[best]), float(b[best]), True)
    # Nothing reachable sees it: keep the configuration nearest to the current one.
    j = int(np.argmin(np.abs(q[:, 0] - q0[0]))) if sensor.has_linear else 0
    return Candidate(q[j], 0.0, float(d[j]), float(b[j]), False)


def ideal_pose(
    sensor: Sensor,
    current: ArrayLike,
    target: Target,
    model: SensorModel,
    radius: float,
    occluders: Sequence[Obstacle] = (),
) -> Candidate:
    """The best pose anywhere within the soft limits (unlimited time: the clairvoyant bound)."""
    big = 1e6
    full = Sensor(sensor.camera_id, sensor.mount, sensor.camera, sensor.limits, True)
    return best_achievable_pose(full, current, target, big, model, radius, 41, occluders)


def visibility_at_poses(
    sensors: dict[str, Sensor],
    model: SensorModel,
    poses: dict[str, ArrayLike],
    target: Target,
    marker_radius: float,
    occluders: Sequence[Obstacle] | None = None,
    only_in_view: bool = True,
    view: Callable[[str, Array], SingleView] | None = None,
) -> float:
    """v_f (eq. 2) of cameras at joint ``poses`` for ``target``: the planner's figure for a
    plan and the evaluation's for what the cameras really saw. ``only_in_view``: a camera
    that would not see the marker (out of view, too oblique, blocked) adds nothing; the
    evaluation passes False for cameras that did image it. ``view``, when given, stands in
    for :func:`view_one` of (camera, joints) with these arguments (the planner's, which
    remembers the views it already weighed)."""
    Rs = []
    for c, q in poses.items():
        qq = np.asarray(q, dtype=np.float64)
        v = (
            view(c, qq)
            if view is not None
            else view_one(sensors[c], qq, target, marker_radius, model, occluders or ())
        )
        if only_in_view and not v.in_view:
            continue
        Rs.append(model.world_covariance(v.distance, v.bearing, v.R, v.blur_px))
    return fused_visibility(Rs)
