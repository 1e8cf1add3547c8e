"""3-D pose of a circle of known radius from its image ellipse (paper Appendix B).

Following Safaee-Rad et al. (1992):

1. (B1) The ellipse and the intrinsics define an oblique elliptic cone with its apex at the
   optical centre: ``X^T Q X = 0`` with ``Q = K^T C K``, C the ellipse's conic matrix.
2. (B2) Its eigen-decomposition reduces it to ``l1 X^2 + l2 Y^2 + l3 Z^2 = 0`` in the canonical
   frame, ordered ``l1 >= l2 > 0 > l3`` (after a sign change of Q if needed).
3. (B3, B4) The planes that cut the cone in a circle have the normals
   ``(+-sqrt((l1 - l2) / (l1 - l3)), 0, sqrt((l2 - l3) / (l1 - l3)))`` in that frame: two
   solutions, which coincide when l1 == l2 (the circle faces the camera).
4. (B5, B6) For each normal, the plane ``n . X = 1`` cuts the cone in a circle of radius r1; the
   circle of the known radius r lies on ``n . X = r / r1``, and its centre follows.

Both solutions reproject to the same ellipse: one view cannot tell them apart. The caller picks
one with a prior normal (:func:`choose_pose`), and reports the choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.geometry import angle_between, cross3, unit
from activesurv_imaging.ellipse import Ellipse
from activesurv_imaging.errors import CirclePoseError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CirclePose:
    """A circle in the camera optical frame (metres).

    Attributes:
        center: (3,) centre of the circle.
        normal: (3,) unit normal, pointing towards the camera (``normal . center < 0``).
    """

    center: Array
    normal: Array


def _in_plane_circle(Q: Array, n: Array) -> tuple[Array, float]:
    """Centre and radius of the cut of the cone ``X^T Q X = 0`` by the plane ``n . X = 1``."""
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = unit(cross3(n, helper))
    e2 = cross3(n, e1)
    B = np.column_stack([e1, e2, n])  # plane coordinates (u, v, 1) -> camera frame
    M = B.T @ Q @ B
    a = 0.5 * (M[0, 0] + M[1, 1])
    if abs(a) < 1e-300:
        raise CirclePoseError('degenerate cone: the plane does not cut it in a circle')
    uv0 = -M[:2, 2] / a
    r2 = float(uv0 @ uv0 - M[2, 2] / a)
    if not r2 > 0.0:
        raise CirclePoseError('degenerate cone: the cut has no real radius')
    return B @ np.array([uv0[0], uv0[1], 1.0]), math.sqrt(r2)


def circle_poses(
    ellipse: Ellipse, camera_matrix: ArrayLike, radius: float
) -> tuple[CirclePose, CirclePose]:
    """Both poses of a circle of ``radius`` whose image is ``ellipse``.

    Args:
        ellipse: the marker boundary in an undistorted image (pixels).
        camera_matrix: 3x3 intrinsics K.
        radius: the circle's radius in metres.

    Returns:
        Two poses in the camera optical frame; the true one is one of them. When the circle
        faces the camera squarely both are the same.

    Raises:
        CirclePoseError: for a bad radius or matrix, or an ellipse that is not the image of a
            circle in front of the camera.
    """
    if not (math.isfinite(radius) and radius > 0.0):
        raise CirclePoseError(f'radius must be finite and > 0, got {radius}')
    K = np.asarray(camera_matrix, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or abs(np.linalg.det(K)) < 1e-12:
        raise CirclePoseError('camera_matrix must be a finite, invertible 3x3 matrix')
    # Scale pixels to about unity first: the conic of a 200-px ellipse is badly conditioned.
    Q = K.T @ ellipse.conic_matrix() @ K
    Q = Q / np.linalg.norm(Q)
    lam, V = np.linalg.eigh(Q)
    if np.count_nonzero(lam > 0) < 2:  # the conic's overall sign is arbitrary
        Q = -Q
        lam, V = np.linalg.eigh(Q)
    if not (lam[1] > 0 and lam[2] > 0 and lam[0] < 0):
        raise CirclePoseError('the ellipse does not back-project to a real elliptic cone')
    l3, l2, l1 = lam  # eigh sorts ascending: l3 < 0 < l2 <= l1
    e3, e1 = V[:, 0], V[:, 2]  # e2 (the l2 axis) lies in both circle planes
    if e3[2] < 0:
        e3 = -e3  # the cone axis points into the scene
    denom = l1 - l3
    g = math.sqrt(max(l1 - l2, 0.0) / denom)
    h = math.sqrt(max(l2 - l3, 0.0) / denom)

    poses = []
    for sign in (1.0, -1.0):
        n = unit(sign * g * e1 + h * e3)
        c1, r1 = _in_plane_circle(Q, n)
        center = (radius / r1) * c1
        if center[2] <= 0.0:
            center = -center
        if center[2] <= 0.0:
            raise CirclePoseError('the circle would be behind the camera')
        normal = n if n @ center < 0.0 else -n
        poses.append(CirclePose(center, normal))
    return poses[0], poses[1]


def choose_pose(
    poses: tuple[CirclePose, CirclePose], prior_normal: ArrayLike
) -> tuple[int, float]:
    """Pick the pose whose normal is closer to ``prior_normal`` (same frame as the poses).

    Returns:
        (index of the chosen pose, margin): the margin is how much closer (radians) the chosen
        normal is to the prior than the other one; near 0 means the choice is uncertain.
    """
    d0 = angle_between(poses[0].normal, prior_normal)
    d1 = angle_between(poses[1].normal, prior_normal)
    return (0, d1 - d0) if d0 <= d1 else (1, d0 - d1)
