"""Motion blur as a model: the marker's ellipse as it was, from the streak it left.

A marker that moves during the exposure is imaged as its ellipse swept along the streak ``s``
(px: where its image went from the exposure's start to its end, at constant velocity): the
image is the ellipse convolved with a line segment. Across a known streak the detector measures
each edge as its area-equivalent edge (:mod:`activesurv_imaging.detect`). Along the motion
that is the edge at mid-exposure; across it, where the segment runs along the edge, less of it
lies inside, and the edge is pulled in by about ``|s|^2 / (24 r)`` (``r``: the local radius of
curvature). So the fitted ellipse has the right centre (the marker at
mid-exposure, the frame's instant) but is too narrow across the motion: a marker 600 mm away
swept 18 px reads 0.16 mm too far (its size is its distance).

:func:`unswept` inverts it: it finds the ellipse whose swept contour is the measured one, by
fixed-point iteration on the ellipse's shape matrix (well defined for a circle, unlike the
axes' angle): ``E <- E + (measured - swept(E))``, each ``swept(E)`` computed from the
swept profile along each normal (the part of the segment inside the ellipse is the interval
between a quadratic's roots) as the detector sees it: the area-equivalent edge. Three rounds
converge to a thousandth of a pixel.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_imaging.ellipse import Ellipse

Array = NDArray[np.float64]

MIN_STREAK = 3.0  # px: shorter streaks move the half-way contour by < 0.01 px: left alone
MAX_STREAK = 200.0  # px: longer is not a marker's streak (a wrong velocity): left alone
ROUNDS = 3
SAMPLES = 64
PROFILE_STEP = 0.2  # px between samples of each swept profile


def shape_matrix(e: Ellipse) -> Array:
    """The 2x2 ``M`` with ``(x - c)^T M (x - c) = 1`` on the ellipse."""
    a, b = e.semi_axes
    ca, sa = math.cos(e.angle), math.sin(e.angle)
    R = np.array([[ca, -sa], [sa, ca]])
    return np.asarray(R @ np.diag([1.0 / (a * a), 1.0 / (b * b)]) @ R.T, dtype=np.float64)


def from_shape(center: ArrayLike, M: Array, rms_residual: float = float('nan')) -> Ellipse:
    """The ellipse of centre ``center`` and shape matrix ``M`` (positive definite).

    Raises:
        ValueError: if ``M`` is not positive definite.
    """
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    if not (w[0] > 0.0 and np.all(np.isfinite(w))):
        raise ValueError(f'not an ellipse: shape matrix eigenvalues {w}')
    # The smaller eigenvalue belongs to the major axis.
    a, b = 1.0 / math.sqrt(w[0]), 1.0 / math.sqrt(w[1])
    major = V[:, 0]
    angle = math.atan2(float(major[1]), float(major[0])) % math.pi
    return Ellipse(np.asarray(center, dtype=np.float64).reshape(2), (a, b), angle, rms_residual)


def _inside_fraction(q: Array, s: Array, c: Array, M: Array) -> Array:
    """For each point ``q`` (N, 2): the fraction of the segment ``q + u s``, ``u`` in
    [-1/2, 1/2], inside the ellipse ``(x - c)^T M (x - c) <= 1``."""
    dx, dy = q[:, 0] - c[0], q[:, 1] - c[1]
    A = float(s @ M @ s)
    ms = M @ s
    B = 2.0 * (dx * ms[0] + dy * ms[1])
    C = M[0, 0] * dx * dx + 2.0 * M[0, 1] * dx * dy + M[1, 1] * dy * dy - 1.0
    disc = B * B - 4.0 * A * C
    root = np.sqrt(np.maximum(disc, 0.0))
    u1 = (-B - root) / (2.0 * A)
    u2 = (-B + root) / (2.0 * A)
    length = np.clip(np.minimum(u2, 0.5) - np.maximum(u1, -0.5), 0.0, 1.0)
    return np.where(disc > 0.0, length, 0.0)


def swept_contour(
    e: Ellipse, streak: ArrayLike, blur_sigma: float = 0.0, n: int = SAMPLES
) -> Array:
    """(n, 2): the edge the detector finds on ``e`` swept along ``streak`` (px) and blurred
    by the lens (``blur_sigma`` px, isotropic): along each of the ellipse's normals, the
    area-equivalent edge of the swept profile (a symmetric blur moves no area edge but by its
    pull on a curved one, which the detector takes out itself; the blur widens the span)."""
    s = np.asarray(streak, dtype=np.float64).reshape(2)
    M = shape_matrix(e)
    c = np.asarray(e.center, dtype=np.float64)
    p = e.points(n)
    normal = (p - c) @ M  # the gradient of the quadratic form: outward
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    sigma = max(float(blur_sigma), 0.0)
    span = 0.5 * float(np.hypot(*s)) + 4.0 * sigma + 1.0
    m = max(16, math.ceil(2.0 * span / PROFILE_STEP) + 1)
    t = np.linspace(-span, span, m)
    q = (p[:, None, :] + normal[:, None, :] * t[None, :, None]).reshape(-1, 2)
    f = _inside_fraction(q, s, c, M).reshape(n, m)
    dt = float(t[1] - t[0])
    edge = dt * (f.sum(axis=1) - 0.5 * (f[:, 0] + f[:, -1])) - span  # the light inside
    return np.asarray(p + normal * edge[:, None], dtype=np.float64)


def _fit_shape(points: Array) -> tuple[Array, Array]:
    """Centre and shape matrix of the algebraic least-squares ellipse through ``points``."""
    x, y = points[:, 0], points[:, 1]
    D = np.column_stack([x * x, x * y, y * y, x, y, np.ones_like(x)])
    _, _, Vt = np.linalg.svd(D, full_matrices=False)
    A, B, C, Dx, Ey, F = Vt[-1]
    Q = np.array([[A, B / 2.0], [B / 2.0, C]])
    c = np.linalg.solve(Q, -0.5 * np.array([Dx, Ey]))
    k = float(c @ Q @ c) - F
    return c, Q / k


def unswept(measured: Ellipse, streak: ArrayLike, blur_sigma: float = 0.0) -> Ellipse:
    """The ellipse that, swept along ``streak`` (px over the exposure) and blurred by
    ``blur_sigma`` px, has the (area-equivalent) contour ``measured``; ``measured`` itself for
    a streak too short to matter or too long to be one. Keeps the measured fit's residual."""
    s = np.asarray(streak, dtype=np.float64).reshape(2)
    length = float(np.hypot(*s))
    if not (math.isfinite(length) and MIN_STREAK <= length <= MAX_STREAK):
        return measured
    target_c = np.asarray(measured.center, dtype=np.float64)
    target_M = shape_matrix(measured)
    c, M = target_c.copy(), target_M.copy()
    for _ in range(ROUNDS):
        try:
            guess = from_shape(c, M)
            seen_c, seen_M = _fit_shape(swept_contour(guess, s, blur_sigma))
        except (ValueError, np.linalg.LinAlgError):
            return measured
        c = c + (target_c - seen_c)
        M = M + (target_M - seen_M)
    try:
        return from_shape(c, M, measured.rms_residual)
    except ValueError:
        return measured
