"""Camera pose in the world from its stage joint states (paper Section III-C-4, Appendix C).

Each dynamic camera sits on a rotary stage (about world z), which may ride on a linear stage.
The *platform* frame P has its origin on the rotation axis, z up (world z), and turns with the
rotary stage::

    T_world_P(s, a) = Trans(base + s * linear_axis) * Rz(yaw_offset + a)

The optical frame hangs off the platform: nominally looking along +x_P, pitched down by
``pitch``, with its centre ``offset`` away from the rotation axis. That offset is what the
moving-camera calibration of Appendix C measures (:func:`solve_rotation_centre`)::

    T_world_cam = T_world_P * (Ry(pitch) * R0, offset)

where R0 maps the optical axes (x right, y down, z forward) to (-y_P, -z_P, +x_P).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, as_vector3, rot_y, rot_z, unit

Array = NDArray[np.float64]

R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # optical -> level platform


@dataclass(frozen=True)
class CameraMount:
    """Where a camera sits and how its stages move it.

    Attributes:
        camera_id: e.g. ``cam1``.
        base: world position (3,) of the rotation axis at linear position 0 (m).
        yaw_offset: world yaw of the optical axis at rotary position 0 (rad).
        pitch: downward tilt of the optical axis (rad).
        offset: camera centre relative to the rotation axis, in the platform frame (m).
        linear_axis: unit world direction of the linear stage, or None for a rotary-only mount.
        linear_joint: joint name of the linear axis (None without one).
        rotary_joint: joint name of the rotary axis.
    """

    camera_id: str
    base: Array
    yaw_offset: float = 0.0
    pitch: float = 0.0
    offset: Array = field(default_factory=lambda: np.zeros(3))
    linear_axis: Array | None = None
    linear_joint: str | None = None
    rotary_joint: str = ''

    def __post_init__(self) -> None:
        object.__setattr__(self, 'base', as_vector3(self.base, f'{self.camera_id} base'))
        object.__setattr__(self, 'offset', as_vector3(self.offset, f'{self.camera_id} offset'))
        if self.linear_axis is not None:
            object.__setattr__(self, 'linear_axis', unit(self.linear_axis, 'linear_axis'))
        if not (math.isfinite(self.yaw_offset) and math.isfinite(self.pitch)):
            raise CalibrationError(f'{self.camera_id}: yaw_offset and pitch must be finite')
        if not self.rotary_joint:
            object.__setattr__(self, 'rotary_joint', f'{self.camera_id}_yaw')
        if self.linear_axis is not None and not self.linear_joint:
            object.__setattr__(self, 'linear_joint', f'{self.camera_id}_x')

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in stage order: linear first (if any), then rotary."""
        if self.linear_joint is not None:
            return (self.linear_joint, self.rotary_joint)
        return (self.rotary_joint,)

    @property
    def R_platform_camera(self) -> Array:
        return np.asarray(rot_y(self.pitch) @ R0, dtype=np.float64)

    def platform_pose(self, linear: float, yaw: float) -> Transform:
        axis = self.linear_axis if self.linear_axis is not None else np.zeros(3)
        return Transform(rot_z(self.yaw_offset + yaw), self.base + linear * axis)

    def camera_pose(self, linear: float, yaw: float) -> Transform:
        """``T_world_camera`` (optical frame) at stage positions ``linear`` (m), ``yaw`` (rad).

        Raises:
            CalibrationError: for non-finite joint values.
        """
        if not (math.isfinite(linear) and math.isfinite(yaw)):
            raise CalibrationError(f'{self.camera_id}: joint positions must be finite')
        if self.linear_axis is None and linear != 0.0:
            raise CalibrationError(f'{self.camera_id} has no linear stage')
        return self.platform_pose(linear, yaw).compose(
            Transform(self.R_platform_camera, self.offset)
        )

    def pose_from_joints(self, q: ArrayLike) -> Transform:
        """``T_world_camera`` from joint positions in stage order (:attr:`joint_names`).

        This is the one rule from a stage state to a camera pose: the simulator renders with
        it, the imager moves its measurements into the world with it, and the dispatcher
        scores poses with it.

        Raises:
            CalibrationError: for the wrong number of joints or non-finite values.
        """
        return self.camera_pose(*self.stage_positions(q))

    def stage_positions(self, q: ArrayLike) -> tuple[float, float]:
        """(linear m, yaw rad) of joint positions ``q`` in stage order (linear 0 without a
        linear stage), checked as :meth:`pose_from_joints` checks them.

        Raises:
            CalibrationError: for the wrong number of joints or non-finite values.
        """
        v = np.asarray(q, dtype=np.float64).reshape(-1)
        if v.shape != (len(self.joint_names),):
            raise CalibrationError(
                f'{self.camera_id}: expected {len(self.joint_names)} joint positions '
                f'{self.joint_names}, got {v.size}'
            )
        linear, yaw = (
            (0.0, float(v[0])) if self.linear_axis is None else (float(v[0]), float(v[1]))
        )
        if not (math.isfinite(linear) and math.isfinite(yaw)):
            raise CalibrationError(f'{self.camera_id}: joint positions must be finite')
        return linear, yaw

    def poses_from_joints(self, q: ArrayLike) -> tuple[Array, Array]:
        """:meth:`pose_from_joints` for many joint vectors at once (the dispatcher scores
        thousands of candidate poses): camera centres (N, 3) and rotations ``R_world_camera``
        (N, 3, 3) for ``q`` (N, J). The same rule; ``test_mount`` holds the two together.
        """
        v = np.atleast_2d(np.asarray(q, dtype=np.float64))
        lin = v[:, 0] if self.linear_axis is not None else np.zeros(len(v))
        yaw = v[:, -1] + self.yaw_offset
        c, s = np.cos(yaw), np.sin(yaw)
        Rz = np.zeros((len(v), 3, 3))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
        axis = self.linear_axis if self.linear_axis is not None else np.zeros(3)
        centres = self.base[None, :] + lin[:, None] * axis[None, :] + Rz @ self.offset
        rotations = np.asarray(Rz @ self.R_platform_camera, dtype=np.float64)
        return np.asarray(centres, dtype=np.float64), rotations

    def camera_pose_from_joints(
        self, names: Sequence[str], positions: Sequence[float]
    ) -> Transform:
        """Camera pose from a JointState's names and positions (other joints are ignored).

        Raises:
            CalibrationError: if a joint of this camera is missing.
        """
        table = dict(zip(names, positions, strict=False))
        if self.rotary_joint not in table:
            raise CalibrationError(f'{self.camera_id}: joint {self.rotary_joint} not in {names}')
        linear = 0.0
        if self.linear_joint is not None:
            if self.linear_joint not in table:
                raise CalibrationError(
                    f'{self.camera_id}: joint {self.linear_joint} not in {list(names)}'
                )
            linear = float(table[self.linear_joint])
        return self.camera_pose(linear, float(table[self.rotary_joint]))

    @property
    def rotation_centre_offset(self) -> Array:
        """The optical centre relative to the rotary axis, in the optical frame at zero rotation.

        The same vector as :attr:`offset`, in the camera's axes (the rig and calibration files
        use this form, as a lab measures it).
        """
        return np.asarray(self.R_platform_camera.T @ self.offset, dtype=np.float64)

    def with_offset(self, offset: ArrayLike) -> CameraMount:
        return CameraMount(
            self.camera_id,
            self.base,
            self.yaw_offset,
            self.pitch,
            np.asarray(offset, dtype=np.float64),
            self.linear_axis,
            self.linear_joint,
            self.rotary_joint,
        )


def mount_to_dict(mount: CameraMount) -> dict[str, Any]:
    """The ``mount`` mapping of rig and calibration files (SI units, world frame).

    ``base`` is the point of the rotary axis at the optical centre's height (at linear position
    0), ``yaw_offset`` the optical axis's world yaw at rotary position 0, ``pitch`` its downward
    tilt, ``rotation_centre_offset`` the optical centre relative to the axis in the optical frame
    at zero rotation, ``linear_axis`` the linear stage's world direction (null without one).
    """
    return {
        'base': [float(v) for v in mount.base],
        'yaw_offset': float(mount.yaw_offset),
        'pitch': float(mount.pitch),
        'rotation_centre_offset': [float(v) for v in mount.rotation_centre_offset],
        'linear_axis': None
        if mount.linear_axis is None
        else [float(v) for v in mount.linear_axis],
    }


def mount_from_dict(camera_id: str, data: Mapping[str, Any]) -> CameraMount:
    """Read a ``mount`` mapping (:func:`mount_to_dict`); ``offset`` (platform frame) is accepted
    in place of ``rotation_centre_offset``.

    Raises:
        CalibrationError: naming the missing or malformed key.
    """
    try:
        pitch = float(data.get('pitch', 0.0))
        axis = data.get('linear_axis')
        linear = None if axis is None or not any(axis) else np.array(axis, dtype=np.float64)
        if 'rotation_centre_offset' in data:
            rco = as_vector3(data['rotation_centre_offset'], f'{camera_id} rotation_centre_offset')
            offset = rot_y(pitch) @ R0 @ rco
        else:
            offset = np.array(data.get('offset', [0.0, 0.0, 0.0]), dtype=np.float64)
        return CameraMount(
            camera_id,
            np.array(data['base'], dtype=np.float64),
            float(data.get('yaw_offset', 0.0)),
            pitch,
            offset,
            linear,
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationError(f'{camera_id}: malformed mount {dict(data)!r}: {exc!r}') from exc


def solve_rotation_centre(
    before: ArrayLike, after: ArrayLike, angles: ArrayLike, pitch: float = 0.0
) -> Array:
    """Rotation centre from target readings before and after camera rotations (eq. C1).

    The target stays put while the camera turns by ``angle`` about the vertical axis. In a
    camera frame whose z is that axis (the paper's camera frame), the target's readings satisfy
    ``R(theta) (P1 - a) + a = P2`` with ``theta = -angle``; ``a`` is the rotation centre. Several
    readings (each pair may use a different angle) are solved together by least squares; the
    paper's fused repeated readings are simply repeated rows.

    Args:
        before: (N, 3) target positions in the optical frame before the rotation (m).
        after: (N, 3) the same targets after the rotation.
        angles: (N,) or scalar rotary-stage rotation between the two readings (rad).
        pitch: the camera's downward tilt, to level the optical frame first.

    Returns:
        (2,) rotation centre (a_x, a_y) in the level camera frame; the camera centre's offset
        from the rotation axis in the platform frame is its negative.

    Raises:
        CalibrationError: for mismatched or non-finite inputs, or rotations too small to solve.
    """
    p1 = np.atleast_2d(np.asarray(before, dtype=np.float64))
    p2 = np.atleast_2d(np.asarray(after, dtype=np.float64))
    ang = np.broadcast_to(np.asarray(angles, dtype=np.float64), (p1.shape[0],))
    if p1.shape != p2.shape or p1.shape[1] != 3:
        raise CalibrationError(f'before/after must both be (N, 3), got {p1.shape}, {p2.shape}')
    if not (np.all(np.isfinite(p1)) and np.all(np.isfinite(p2)) and np.all(np.isfinite(ang))):
        raise CalibrationError('readings and angles must be finite')
    level = rot_y(pitch) @ R0  # optical -> level camera frame (the platform's axes)
    q1 = p1 @ level.T
    q2 = p2 @ level.T
    rows, rhs = [], []
    for a1, a2, angle in zip(q1, q2, ang, strict=True):
        R = rot_z(-angle)[:2, :2]
        rows.append(np.eye(2) - R)
        rhs.append(a2[:2] - R @ a1[:2])
    A = np.vstack(rows)
    b = np.concatenate(rhs)
    if np.linalg.matrix_rank(A, tol=1e-6) < 2:
        raise CalibrationError('the rotations are too small to locate the rotation centre')
    centre, *_ = np.linalg.lstsq(A, b, rcond=None)
    return np.asarray(centre, dtype=np.float64)
