"""Commissioning of a dynamic camera from views of a checkerboard the xy table carries.

The table puts the board at known world poses (its own positions plus the board's fixture on
the carriage); the camera's stages are driven through *stations* (joint positions) and at each
station the camera images the board at several table positions, near and far. All corners seen
at one station are one non-planar view in world coordinates, so:

1. **Intrinsics and per-station extrinsics** come from ``cv2.calibrateCamera`` over all
   stations (a 3-D target; the nominal intrinsics start it). Only ``k1`` is estimated: on a
   7-degree lens ``k2``/``k3`` trade against the focal length (see
   :func:`activesurv_imaging.calibration.calibrate_intrinsics`); tangential terms are zero.
2. **The mount** (base, yaw offset, pitch, the optical centre's offset from the rotary axis)
   is the least-squares fit of the stage kinematics (:class:`CameraMount`) to every station's
   extrinsics and reported joint positions.
3. **The rotation centre by eq. C1** (the paper's Appendix C), as a check: the board's position
   in the camera frame before and after turning the rotary stage, with the board fixed.

A narrow lens can tell its principal point from a small turn of the camera only by how the
board's image changes across the frame (the two move it alike to within (x/z)^2 ~ 0.4 %): the
refinement weights each sighting's shape by the corner finder's scatter and its place by the
table's and stages' accuracy (:class:`NoiseModel`) so that this shape counts; what the views
cannot carry the mount fit absorbs, and the pair predicts rays in the world as well as the
truth does (docs/commissioning.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, rot_y
from activesurv_common.mount import R0, CameraMount, solve_rotation_centre
from activesurv_imaging.errors import CalibrationError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class BoardSighting:
    """The board's corners (N, 2 px) as seen with the board at ``T_world_board``."""

    T_world_board: Transform
    corners: Array


@dataclass(frozen=True)
class Station:
    """A camera at one set of stage positions, and what it saw of the board there."""

    joints: Array
    sightings: tuple[BoardSighting, ...]


def order_like(corners: Array, expected: Array) -> Array:
    """``corners`` in the order of ``expected`` (the board projected with the nominal camera):
    a board seen obliquely can fool the dark-square test of
    :func:`activesurv_imaging.calibration.find_corners` into the reverse order."""
    if np.dot(corners[-1] - corners[0], expected[-1] - expected[0]) < 0.0:
        return np.asarray(corners[::-1], dtype=np.float64)
    return corners


def station_pose(station: Station, camera: CameraModel, board: Array) -> Transform | None:
    """``T_world_camera`` at a station from its nearest board sighting (planar PnP)."""
    best: tuple[float, Transform] | None = None
    for s in station.sightings:
        ok, rvec, tvec = cv2.solvePnP(
            board, s.corners, camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE
        )
        if not ok:
            continue
        R, _ = cv2.Rodrigues(rvec)
        t = np.asarray(tvec, dtype=np.float64).ravel()
        T_cb = Transform(np.asarray(R, dtype=np.float64), t)
        T = s.T_world_board.compose(T_cb.inverse())
        if best is None or t[2] < best[0]:
            best = (float(t[2]), T)
    return None if best is None else best[1]


def _mount(nominal: CameraMount, x: Array) -> CameraMount:
    return CameraMount(
        nominal.camera_id,
        x[0:3],
        float(x[3]),
        float(x[4]),
        np.array([x[5], x[6], 0.0]),
        nominal.linear_axis,
        nominal.linear_joint,
        nominal.rotary_joint,
    )


def _mount_vector(m: CameraMount) -> Array:
    return np.asarray(np.r_[m.base, m.yaw_offset, m.pitch, m.offset[:2]], dtype=np.float64)


def mount_from_poses(
    nominal: CameraMount, joints: Sequence[Array], poses: Sequence[Transform]
) -> CameraMount:
    """The mount whose kinematics best explain camera poses measured at joint positions.

    Raises:
        CalibrationError: with fewer than 2 poses or no convergence.
    """
    from scipy.optimize import least_squares  # scipy.optimize is slow to load: fits only

    if len(poses) < 2:
        raise CalibrationError(f'{len(poses)} station poses; need >= 2 to fit a mount')

    def residuals(x: Array) -> Array:
        m = _mount(nominal, x)
        out = []
        for q, T in zip(joints, poses, strict=True):
            P = m.pose_from_joints(q)
            out.append(P.t - T.t)
            out.append(0.5 * (P.R - T.R).ravel())  # ~ rad at a 0.5 m lever
        return np.concatenate(out)

    fit = least_squares(residuals, _mount_vector(nominal), method='lm')
    if not fit.success:
        raise CalibrationError(f'the mount fit did not converge: {fit.message}')
    return _mount(nominal, fit.x)


def _sightings(stations: Sequence[Station], board: Array) -> list[tuple[Array, Array, Array]]:
    """Every sighting as (joints, its corners in world coordinates (N, 3), pixels (N, 2))."""
    return [
        (
            np.asarray(st.joints, dtype=np.float64),
            board @ s.T_world_board.R.T + s.T_world_board.t,
            np.asarray(s.corners, dtype=np.float64),
        )
        for st in stations
        for s in st.sightings
    ]


OUTLIER_FACTOR = 4.0
"""A sighting whose corners scatter more than this many times the median sighting's is left out
of the fit (:func:`outlying_sightings`)."""
OUTLIER_FLOOR = 0.1
"""px: ... and more than this (a clean rig's corners scatter by 0.03-0.09 px)."""
MAX_DROPPED = 0.2
"""At most this share of the sightings is ever left out."""


def outlying_sightings(residuals: Sequence[Array]) -> list[int]:
    """The sightings whose corners scatter far more about their own mean than the others' do:
    a frame taken while a stage or the table still moved, or corners found on clutter. Their
    indices (at most :data:`MAX_DROPPED` of them, the worst first kept out), in order.

    Args:
        residuals: each sighting's reprojection residuals (N, 2) after a first fit.
    """
    if not residuals:
        return []
    shape = np.array([math.sqrt(float(np.mean((r - r.mean(axis=0)) ** 2))) for r in residuals])
    limit = max(OUTLIER_FACTOR * float(np.median(shape)), OUTLIER_FLOOR)
    worst = [int(i) for i in np.argsort(-shape) if shape[i] > limit]
    return sorted(worst[: int(MAX_DROPPED * len(residuals))])


@dataclass(frozen=True)
class NoiseModel:
    """How far corners are off what the model predicts, split in two (px, per image axis).

    Attributes:
        corner: each corner on its own (the corner finder), after the sighting's mean is
            taken out; the shape of the board's image.
        sighting: the whole sighting moved together (where the table and the stages really
            were, Table I accuracy): the mean of a sighting's residuals, less what ``corner``
            puts there.
    """

    corner: float
    sighting: float

    @staticmethod
    def of(residuals: Sequence[Array]) -> NoiseModel:
        means = np.array([r.mean(axis=0) for r in residuals])
        centred = np.concatenate([(r - r.mean(axis=0)).ravel() for r in residuals])
        n = float(np.mean([len(r) for r in residuals]))
        corner = max(float(np.sqrt(np.mean(centred**2))), 1e-3)
        mean_var = float(np.mean(means**2)) - corner**2 / n
        return NoiseModel(corner, max(math.sqrt(max(mean_var, 0.0)), 1e-3))

    def whiten(self, r: Array) -> Array:
        """One sighting's residuals (N, 2) as independent unit-variance terms."""
        mu = r.mean(axis=0)
        mean_std = math.sqrt(self.sighting**2 + self.corner**2 / len(r))
        return np.concatenate([((r - mu) / self.corner).ravel(), mu / mean_std])


@dataclass(frozen=True)
class Refinement:
    """What :func:`refine` found.

    Attributes:
        camera, mount: the estimates.
        rms: RMS reprojection error over every corner (px).
        noise: the noise model of the weighted pass.
        std: the estimates' standard deviations from that noise model (the inverse of the
            weighted Gauss-Newton normal matrix): fx, fy, cx, cy (px), k1, base x, y, z (m),
            yaw offset, pitch (rad), offset x, y (m).
        dropped: the sightings left out as outliers (:func:`outlying_sightings`).
    """

    camera: CameraModel
    mount: CameraMount
    rms: float
    noise: NoiseModel
    std: Array
    dropped: int = 0


def refine(
    camera: CameraModel,
    mount: CameraMount,
    stations: Sequence[Station],
    board: Array,
) -> Refinement:
    """Intrinsics (fx, fy, cx, cy, k1) and mount together, from every corner of every station
    through the stage kinematics (a bundle adjustment with the board's poses known).

    Two passes: the plain least-squares fit, then the same fit weighted by what its residuals
    show (:class:`NoiseModel`). Table and stage errors move a whole sighting by ~0.1 px while
    the corner finder scatters single corners by ~0.03 px; weighting each sighting's shape
    by the one and its place by the other is the maximum-likelihood fit, and it is what lets
    the board's shape across the image (the only thing that tells the principal point from a
    turn of the camera) count. Between the two, sightings whose corners scatter far more than
    the others' (:func:`outlying_sightings`) are left out and the plain fit made again.

    Returns:
        the estimates, the RMS reprojection error, the noise model and the uncertainties.

    Raises:
        CalibrationError: with fewer than 3 stations or no convergence.
    """
    from scipy.optimize import least_squares  # scipy.optimize is slow to load: fits only

    seen = sum(1 for s in stations if s.sightings)
    if seen < 3:
        raise CalibrationError(f'{seen} stations saw the board; need >= 3')
    data = _sightings(stations, board)

    def model_of(x: Array) -> CameraModel:
        K = np.array([[x[0], 0.0, x[2]], [0.0, x[1], x[3]], [0.0, 0.0, 1.0]])
        dist = np.array([x[4], 0.0, 0.0, 0.0, 0.0])
        # Response, exposure and lens settings are not fitted here: kept as they were.
        return replace(camera, K=K, dist=dist)

    def raw(x: Array) -> list[Array]:
        cam, m = model_of(x[:5]), _mount(mount, x[5:])
        out = []
        for q, obj, img in data:
            T = m.pose_from_joints(q)
            out.append(cam.project((obj - T.t) @ T.R) - img)
        return out

    def fit(residuals: Callable[[Array], Array], x0: Array) -> Array:
        result = least_squares(
            residuals, x0, x_scale=scale, method='lm', xtol=1e-10, ftol=1e-10, max_nfev=2000
        )
        if not result.success:
            raise CalibrationError(f'the refinement did not converge: {result.message}')
        return np.asarray(result.x, dtype=np.float64)

    x0 = np.r_[camera.fx, camera.fy, camera.cx, camera.cy, camera.dist[0], _mount_vector(mount)]
    scale = np.r_[10.0, 10.0, 1.0, 1.0, 0.01, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3]

    def plain(x: Array) -> Array:
        return np.concatenate([r.ravel() for r in raw(x)])

    x1 = fit(plain, x0)
    # A sighting whose corners scatter far more than the rest is not what the noise model
    # describes: left out, and the plain fit made again without it.
    if dropped := outlying_sightings(raw(x1)):
        left_out = set(dropped)
        data = [d for i, d in enumerate(data) if i not in left_out]
        x1 = fit(plain, x1)
    noise = NoiseModel.of(raw(x1))

    def whitened(x: Array) -> Array:
        return np.concatenate([noise.whiten(r) for r in raw(x)])

    x2 = fit(whitened, x1)
    rms = float(np.sqrt(np.mean(np.concatenate([r.ravel() for r in raw(x2)]) ** 2) * 2))
    steps = np.diag(scale * 1e-4)  # central differences: the Jacobian at the solution
    jac = np.column_stack(
        [(whitened(x2 + h) - whitened(x2 - h)) / (2.0 * h[i]) for i, h in enumerate(steps)]
    )
    std = np.sqrt(np.clip(np.diag(np.linalg.inv(jac.T @ jac)), 0.0, None))
    return Refinement(model_of(x2[:5]), _mount(mount, x2[5:]), rms, noise, std, len(dropped))


def commission_camera(
    nominal_camera: CameraModel,
    nominal_mount: CameraMount,
    stations: Sequence[Station],
    board: Array,
) -> Refinement:
    """The whole procedure for one camera: station poses by PnP with the nominal optics, a
    first mount from them, then intrinsics and mount refined over every corner (:func:`refine`).
    """
    poses, joints = [], []
    for s in stations:
        T = station_pose(s, nominal_camera, board)
        if T is not None:
            poses.append(T)
            joints.append(np.asarray(s.joints, dtype=np.float64))
    mount0 = mount_from_poses(nominal_mount, joints, poses)
    return refine(nominal_camera, mount0, stations, board)


def board_centre_in_camera(sighting: BoardSighting, camera: CameraModel, board: Array) -> Array:
    """The board's centre in the camera's optical frame (m), by PnP with ``camera``."""
    ok, _, tvec = cv2.solvePnP(
        board, sighting.corners, camera.K, camera.dist, flags=cv2.SOLVEPNP_ITERATIVE
    )
    if not ok:
        raise CalibrationError('solvePnP failed on a board sighting')
    return np.asarray(tvec, dtype=np.float64).reshape(3)


def c1_offset(
    pairs: Sequence[tuple[BoardSighting, BoardSighting, float]],
    camera: CameraModel,
    board: Array,
    pitch: float,
) -> Array:
    """The optical centre's offset from the rotary axis by eq. C1 (optical frame, zero yaw).

    Args:
        pairs: (before, after, rotation in rad) with the board fixed in between.
        camera: calibrated intrinsics.
        board: board corners in the board frame.
        pitch: the camera's pitch (from the mount fit), to level its frame.

    Raises:
        CalibrationError: for no pairs or rotations too small to solve.
    """
    if not pairs:
        raise CalibrationError('eq. C1 needs readings before and after a rotation')
    before = np.array([board_centre_in_camera(b, camera, board) for b, _, _ in pairs])
    after = np.array([board_centre_in_camera(a, camera, board) for _, a, _ in pairs])
    angles = np.array([angle for _, _, angle in pairs])
    centre = solve_rotation_centre(before, after, angles, pitch)
    # The rotation centre in the level camera frame; the camera centre's offset from the axis
    # in the platform frame is its negative, and in the optical frame at zero rotation:
    offset_platform = -np.array([centre[0], centre[1], 0.0])
    level = rot_y(pitch) @ R0
    return np.asarray(level.T @ offset_platform, dtype=np.float64)


def pixel_error(
    truth: CameraModel,
    truth_mount: CameraMount,
    model: CameraModel,
    mount: CameraMount,
    q: Array,
    depth: float = 0.5,
) -> float:
    """Largest image distance (px) between where the true camera sees world points at
    ``depth`` and where the calibrated camera (intrinsics and mount) puts them, at joints ``q``:
    the calibration error that reaches the measurements, whatever the split between them."""
    T_true = truth_mount.pose_from_joints(q)
    T_cal = mount.pose_from_joints(q)
    u, v = np.meshgrid(np.linspace(0, truth.width - 1, 5), np.linspace(0, truth.height - 1, 4))
    px = np.column_stack([u.ravel(), v.ravel()])
    world = (truth.rays(px) * depth) @ T_true.R.T + T_true.t
    pc = (world - T_cal.t) @ T_cal.R
    return float(np.max(np.linalg.norm(model.project(pc) - px, axis=1)))


__all__ = [
    'BoardSighting',
    'NoiseModel',
    'Refinement',
    'Station',
    'board_centre_in_camera',
    'c1_offset',
    'commission_camera',
    'mount_from_poses',
    'order_like',
    'outlying_sightings',
    'pixel_error',
    'refine',
    'station_pose',
]
