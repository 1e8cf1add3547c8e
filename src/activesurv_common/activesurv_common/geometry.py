"""Rigid-body geometry shared by the imaging, fusion and dispatch cores.

Conventions (REP 103): right-handed frames, metres and radians, quaternions as (x, y, z, w).
A :class:`Transform` ``T_a_b`` maps points expressed in frame ``b`` into frame ``a``:
``p_a = T_a_b.apply(p_b)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.errors import GeometryError

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]

_EPS = 1e-12


def as_vector3(value: ArrayLike, name: str = 'vector') -> Vector:
    """Return ``value`` as a finite float (3,) array.

    Raises:
        GeometryError: if it is not three finite numbers.
    """
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    if v.shape != (3,):
        raise GeometryError(f'{name} must have 3 components, got shape {v.shape}')
    if not np.all(np.isfinite(v)):
        raise GeometryError(f'{name} must be finite, got {v.tolist()}')
    return v


def unit(value: ArrayLike, name: str = 'vector') -> Vector:
    """Return ``value`` normalised to unit length.

    Raises:
        GeometryError: for a non-finite or (near) zero vector.
    """
    v = as_vector3(value, name)
    n = float(np.linalg.norm(v))
    if n < _EPS:
        raise GeometryError(f'{name} has zero length and no direction')
    return v / n


def rot_x(angle: float) -> Matrix:
    """Rotation matrix about +x by ``angle`` radians."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> Matrix:
    """Rotation matrix about +y by ``angle`` radians."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def cross3(a: ArrayLike, b: ArrayLike) -> Vector:
    """The cross product of two 3-vectors: ``np.cross`` without its axis handling (40 us a call
    against 2 us; a frame's pose and a plan's visibility call it many times)."""
    a0, a1, a2 = np.asarray(a, dtype=np.float64).reshape(3).tolist()
    b0, b1, b2 = np.asarray(b, dtype=np.float64).reshape(3).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def rot_z(angle: float) -> Matrix:
    """Rotation matrix about +z by ``angle`` radians."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def skew(v: ArrayLike) -> Matrix:
    """The cross-product matrix ``[v]x`` with ``skew(v) @ w == cross(v, w)``."""
    x, y, z = as_vector3(v)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_between(a: ArrayLike, b: ArrayLike) -> Matrix:
    """The smallest rotation taking direction ``a`` onto direction ``b``."""
    ua, ub = unit(a, 'a'), unit(b, 'b')
    axis = cross3(ua, ub)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(ua, ub))
    if s < 1e-12:
        if c > 0.0:
            return np.eye(3)
        # Antiparallel: any axis perpendicular to a works; take the most stable one.
        helper = np.eye(3)[int(np.argmin(np.abs(ua)))]
        axis = unit(cross3(ua, helper))
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = skew(axis / s)
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def quaternion_from_matrix(R: ArrayLike) -> Vector:
    """Unit quaternion (x, y, z, w) of a rotation matrix, with w >= 0."""
    m = np.asarray(R, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise GeometryError('rotation matrix must be a finite 3x3 array')
    tr = float(np.trace(m))
    if tr > 0.0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array(
            [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
        )
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(max(1.0 + m[i, i] - m[j, j] - m[k, k], _EPS))
        q = np.zeros(4)
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
        q[3] = (m[k, j] - m[j, k]) / s
    q /= np.linalg.norm(q)
    return -q if q[3] < 0.0 else q


def matrix_from_quaternion(q: ArrayLike) -> Matrix:
    """Rotation matrix of a quaternion (x, y, z, w); the quaternion is normalised first.

    Raises:
        GeometryError: for a non-finite or zero quaternion.
    """
    v = np.asarray(q, dtype=np.float64).reshape(-1)
    if v.shape != (4,) or not np.all(np.isfinite(v)):
        raise GeometryError(f'quaternion must be 4 finite numbers, got {v.tolist()}')
    n = float(np.linalg.norm(v))
    if n < _EPS:
        raise GeometryError('quaternion has zero length')
    x, y, z, w = v / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_from_normal(normal: ArrayLike) -> Vector:
    """Orientation of a marker frame whose +z axis is ``normal`` (rotation about it unobserved).

    The marker's in-plane rotation cannot be measured from a circle; the smallest rotation from
    world +z is the convention used for it.
    """
    return quaternion_from_matrix(rotation_between((0.0, 0.0, 1.0), normal))


def normal_from_quaternion(q: ArrayLike) -> Vector:
    """The +z axis of the frame with orientation ``q``."""
    return matrix_from_quaternion(q)[:, 2].copy()


def normal_to_rotation_covariance(
    normal: ArrayLike, normal_cov: ArrayLike, unobserved_variance: float = np.pi**2
) -> Matrix:
    """Covariance of a small rotation vector equivalent to a covariance of a unit normal.

    A rotation ``dtheta`` perpendicular to ``n`` moves the normal by ``dn = dtheta x n``, so
    ``dtheta = n x dn``. Rotation about ``n`` itself is not observable from a circle; it gets
    ``unobserved_variance``.
    """
    n = unit(normal, 'normal')
    c = np.asarray(normal_cov, dtype=np.float64)
    if c.shape != (3, 3):
        raise GeometryError(f'normal covariance must be 3x3, got {c.shape}')
    k = skew(n)
    out = k @ c @ k.T + unobserved_variance * np.outer(n, n)
    return 0.5 * (out + out.T)


def angle_between(a: ArrayLike, b: ArrayLike) -> float:
    """Angle in radians between two directions (robust near 0 and pi)."""
    ua, ub = unit(a, 'a'), unit(b, 'b')
    return float(np.arctan2(np.linalg.norm(cross3(ua, ub)), np.dot(ua, ub)))


def bearings(to_camera: ArrayLike, normal: ArrayLike) -> NDArray[np.float64]:
    """The bearing theta of the sensor model (Appendix A): the angle (rad) between a marker's
    normal and the line from the marker to the camera, for (N, 3) (or one (3,)) such lines."""
    v = np.atleast_2d(np.asarray(to_camera, dtype=np.float64))
    n = np.asarray(normal, dtype=np.float64).reshape(3)
    n = n / np.linalg.norm(n)
    d = np.maximum(np.linalg.norm(v, axis=1), 1e-12)
    return np.asarray(np.arccos(np.clip((v @ n) / d, -1.0, 1.0)), dtype=np.float64)


def bearing(to_camera: ArrayLike, normal: ArrayLike) -> float:
    """:func:`bearings` of one line from the marker to the camera."""
    return float(bearings(to_camera, normal)[0])


@dataclass(frozen=True)
class Transform:
    """A rigid transform ``T_a_b``: rotation ``R`` (3x3) and translation ``t`` (3,)."""

    R: Matrix
    t: Vector

    @staticmethod
    def identity() -> Transform:
        return Transform(np.eye(3), np.zeros(3))

    @staticmethod
    def about_z(angle: float, t: ArrayLike) -> Transform:
        """A rotation by ``angle`` (rad) about +z, then the translation ``t``, with its
        quaternion known at once (a stage's frame on every joint state: no matrix to undo).

        Raises:
            GeometryError: for a non-finite angle or translation.
        """
        v = np.asarray(t, dtype=np.float64).reshape(-1)
        if v.shape != (3,) or not all(map(math.isfinite, [angle, *v.tolist()])):
            raise GeometryError(f'need a finite angle and 3-vector, got {angle!r}, {v.tolist()}')
        c, s = math.cos(angle), math.sin(angle)
        out = Transform(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), v)
        s, c = math.sin(0.5 * angle), math.cos(0.5 * angle)
        q = np.array([0.0, 0.0, -s, -c] if c < 0.0 else [0.0, 0.0, s, c])  # w >= 0
        object.__setattr__(out, '_quaternion', q)
        return out

    @staticmethod
    def from_rt(R: ArrayLike, t: ArrayLike) -> Transform:
        """Build a transform, checking that ``R`` is a proper rotation."""
        m = np.asarray(R, dtype=np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise GeometryError('rotation must be a finite 3x3 matrix')
        if not np.allclose(m @ m.T, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0.0:
            raise GeometryError('rotation matrix is not orthonormal with det +1')
        return Transform(m, as_vector3(t, 'translation'))

    def apply(self, p: ArrayLike) -> Vector:
        """Map a point from frame b to frame a."""
        return self.R @ as_vector3(p, 'point') + self.t

    def rotate(self, v: ArrayLike) -> Vector:
        """Map a direction from frame b to frame a."""
        return self.R @ as_vector3(v, 'direction')

    def compose(self, other: Transform) -> Transform:
        """``T_a_b.compose(T_b_c) == T_a_c``."""
        return Transform(self.R @ other.R, self.R @ other.t + self.t)

    def inverse(self) -> Transform:
        return Transform(self.R.T, -(self.R.T @ self.t))

    def quaternion(self) -> Vector:
        """The rotation's unit quaternion (x, y, z, w), worked out once per transform (an
        imager's camera pose is converted ahead of its instant; its message takes it then)."""
        q = self.__dict__.get('_quaternion')
        if q is None:
            q = quaternion_from_matrix(self.R)
            object.__setattr__(self, '_quaternion', q)  # a frozen value's cache, not a field
        return np.array(q)
