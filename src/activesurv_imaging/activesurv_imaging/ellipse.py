"""Weighted least-squares ellipse fit (paper eq. 3-4) and the five ellipse parameters.

The fit minimises ``J = sum_i (w_i Q(X_i, Y_i))^2`` over the conic
``Q(X, Y) = aX^2 + bXY + cY^2 + dX + eY + f`` under the ellipse constraint ``4ac - b^2 = 1``
(Fitzgibbon et al. 1999, in the numerically stable form of Halir and Flusser 1998), on
coordinates centred and scaled for conditioning.

The weights ``w_i`` correct the two non-uniformities the paper names:

* **point density along the boundary**: edge pixels are not evenly spaced in arc length (a
  pixel chain steps 1 px along the axes and sqrt(2) px diagonally; points are denser where the
  boundary is flatter in image space). Each point gets the arc length it represents, ``s_i``, half
  the distance to each neighbour along the ellipse, so the sum approximates a line integral.
* **the algebraic distance**: ``Q`` grows with ``|grad Q|``, which varies around the ellipse
  (largest at the ends of the major axis), so an unweighted fit is pulled towards the minor
  axis and shrinks. Dividing by ``|grad Q|`` (from the previous iterate) turns ``Q`` into the
  first-order geometric distance (Sampson).

So ``w_i = sqrt(s_i) / |grad Q(X_i, Y_i)|``, and the fit is iterated (re-weighted) until the
conic stops changing. With user-supplied ``weights`` the fit is a single weighted solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_imaging.errors import EllipseFitError
from activesurv_imaging.kernels import (
    arc_weights,
    direct_fit,
    ellipse_parameters,
    reweighted_fit,
    sampson,
    sampson_weights,
    scatter,
)

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Ellipse:
    """An ellipse in image coordinates (pixels, x right, y down).

    Attributes:
        center: (2,) centre (x, y).
        semi_axes: (a, b) with a >= b > 0.
        angle: radians, direction of the major axis from the +x image axis, in [0, pi).
        rms_residual: RMS geometric (Sampson) distance of the fitted points, pixels
            (NaN when unknown).
    """

    center: Array
    semi_axes: tuple[float, float]
    angle: float
    rms_residual: float = float('nan')

    def conic(self) -> Array:
        """Normalised conic (a, b, c, d, e, f) of the ellipse, with unit norm and a + c > 0."""
        a, b = self.semi_axes
        cx, cy = self.center
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        A = ca * ca / (a * a) + sa * sa / (b * b)
        B = 2.0 * ca * sa * (1.0 / (a * a) - 1.0 / (b * b))
        C = sa * sa / (a * a) + ca * ca / (b * b)
        D = -2.0 * A * cx - B * cy
        E = -B * cx - 2.0 * C * cy
        F = A * cx * cx + B * cx * cy + C * cy * cy - 1.0
        v = np.array([A, B, C, D, E, F])
        return np.asarray(v / np.linalg.norm(v), dtype=np.float64)

    def conic_matrix(self) -> Array:
        """Symmetric 3x3 matrix C with [x y 1] C [x y 1]^T = Q(x, y)."""
        A, B, C, D, E, F = self.conic()
        return np.array([[A, B / 2, D / 2], [B / 2, C, E / 2], [D / 2, E / 2, F]])

    def points(self, n: int = 360) -> Array:
        """``n`` points on the ellipse, evenly spaced in the parametric angle."""
        t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
        a, b = self.semi_axes
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        x = a * np.cos(t)
        y = b * np.sin(t)
        return np.column_stack(
            [self.center[0] + ca * x - sa * y, self.center[1] + sa * x + ca * y]
        )

    @property
    def area(self) -> float:
        return math.pi * self.semi_axes[0] * self.semi_axes[1]


def ellipse_from_conic(conic: ArrayLike) -> Ellipse:
    """The five parameters of the ellipse ``aX^2 + bXY + cY^2 + dX + eY + f = 0``.

    Raises:
        EllipseFitError: if the conic is not a real, non-degenerate ellipse.
    """
    A, B, C, D, E, F = (float(v) for v in np.asarray(conic, dtype=np.float64).reshape(6))
    if not all(math.isfinite(v) for v in (A, B, C, D, E, F)):
        raise EllipseFitError('conic has non-finite coefficients')
    disc = 4.0 * A * C - B * B
    if disc <= 0.0:
        raise EllipseFitError(f'conic is not an ellipse (4ac - b^2 = {disc:.3g} <= 0)')
    cx, cy, a, b, angle = ellipse_parameters(A, B, C, D, E, F)
    if not math.isfinite(cx):
        raise EllipseFitError('conic is an imaginary or degenerate ellipse')
    return Ellipse(np.array([cx, cy]), (float(a), float(b)), float(angle))


CONVERGED = 1e-7  # change of the unit-norm conic at which re-weighting stops


def _direct_fit(x: Array, y: Array, w: Array) -> Array:
    """Weighted constrained fit (Halir-Flusser); returns the conic in the given coordinates
    (compiled: :func:`activesurv_imaging.kernels.direct_fit`; numpy's complex ``eig`` when
    the reduced problem's eigenvalues are not all real)."""
    try:
        conic = direct_fit(x, y, w)
    except np.linalg.LinAlgError as exc:
        raise EllipseFitError('points are degenerate (collinear or too few)') from exc
    except ValueError:
        return _direct_fit_numpy(x, y, w)
    if not np.all(np.isfinite(conic)):
        raise EllipseFitError('no ellipse fits these points')
    return conic


def _direct_fit_numpy(x: Array, y: Array, w: Array) -> Array:
    """:func:`_direct_fit` in numpy, complex eigenvalues and all."""
    S = scatter(x, y, w)
    S1, S2, S3 = S[:3, :3], S[:3, 3:], S[3:, 3:]
    try:
        T = -np.linalg.solve(S3, S2.T)
    except np.linalg.LinAlgError as exc:
        raise EllipseFitError('points are degenerate (collinear or too few)') from exc
    M = S1 + S2 @ T
    M = np.array([M[2] / 2.0, -M[1], M[0] / 2.0])  # C1^-1 M
    vals, vecs = np.linalg.eig(M)
    vecs = np.real(vecs)
    cond = 4.0 * vecs[0] * vecs[2] - vecs[1] ** 2
    ok = np.nonzero(cond > 0.0)[0]
    if ok.size == 0:
        raise EllipseFitError('no ellipse fits these points')
    a1 = vecs[:, ok[int(np.argmin(np.abs(np.real(vals[ok]))))]]
    return np.concatenate([a1, T @ a1])


def _reweighted_numpy(u: Array, v: Array, arc: Array, conic_n: Array, iterations: int) -> Array:
    """:func:`activesurv_imaging.kernels.reweighted_fit` with numpy's complex ``eig``."""
    for _ in range(iterations):
        new = _direct_fit_numpy(u, v, sampson_weights(u, v, arc, conic_n))
        new *= np.sign(new @ conic_n) / np.linalg.norm(new)
        # Converged when the unit conic moves less than 1e-7 (the centre by ~1e-6 px).
        done = np.linalg.norm(new - conic_n / np.linalg.norm(conic_n)) < CONVERGED
        conic_n = new
        if done:
            break
    return conic_n


def _denormalise(conic: Array, mx: float, my: float, s: float) -> Array:
    """Conic in pixel coordinates from one fitted on u = (x - mx) * s, v = (y - my) * s."""
    A, B, C, D, E, F = conic
    A2, B2, C2 = A * s * s, B * s * s, C * s * s
    D2, E2 = D * s, E * s
    return np.array(
        [
            A2,
            B2,
            C2,
            D2 - 2 * A2 * mx - B2 * my,
            E2 - 2 * C2 * my - B2 * mx,
            A2 * mx * mx + B2 * mx * my + C2 * my * my - D2 * mx - E2 * my + F,
        ]
    )


def _arc_weights(u: Array, v: Array, ell: Ellipse) -> Array:
    """Arc length represented by each point: half the gap to its neighbours around the ellipse."""
    (a, b), (cx, cy) = ell.semi_axes, ell.center
    return arc_weights(u, v, float(cx), float(cy), a, b, ell.angle)


def sampson_distances(conic: ArrayLike, points: ArrayLike) -> Array:
    """First-order geometric distance ``|Q| / |grad Q|`` of each point to the conic (pixels)."""
    c = np.ascontiguousarray(conic, dtype=np.float64).reshape(6)
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    return sampson(c, p)


def fit_ellipse(
    points: ArrayLike, weights: ArrayLike | None = None, iterations: int = 6
) -> Ellipse:
    """Fit an ellipse to boundary points by weighted least squares (eq. 3-4).

    Args:
        points: (N, 2) image coordinates (x right, y down, pixels), N >= 5, in any order.
        weights: optional (N,) fixed weights ``w_i`` of eq. 3 (one solve). ``None`` (default)
            uses the density and gradient weights described in the module docstring,
            re-weighted ``iterations`` times.
        iterations: maximum re-weighting passes for the default weights.

    Returns:
        The ellipse, with the RMS Sampson distance of the points as ``rms_residual``.

    Raises:
        EllipseFitError: for fewer than 5 finite points, bad weights, or points no ellipse fits.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise EllipseFitError(f'points must be an (N, 2) array, got shape {p.shape}')
    if p.shape[0] < 5:
        raise EllipseFitError(f'an ellipse needs at least 5 points, got {p.shape[0]}')
    if not np.all(np.isfinite(p)):
        raise EllipseFitError('points contain NaN or infinite values')
    mx, my = p.mean(axis=0)
    spread = float(np.sqrt(((p - [mx, my]) ** 2).sum(axis=1).mean()))
    if spread < 1e-9:
        raise EllipseFitError('all points coincide')
    s = math.sqrt(2.0) / spread
    u, v = (p[:, 0] - mx) * s, (p[:, 1] - my) * s

    if weights is not None:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != (p.shape[0],) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise EllipseFitError('weights must be N finite, non-negative numbers')
        if np.count_nonzero(w) < 5:
            raise EllipseFitError('fewer than 5 points have non-zero weight')
        conic_n = _direct_fit(u, v, w)
    else:
        conic_n = _direct_fit(u, v, np.ones_like(u))
        # Arc lengths from the first fit: the points' order and spacing around the ellipse do
        # not change with the small corrections of the re-weighting (only |grad Q| does).
        arc = np.sqrt(_arc_weights(u, v, ellipse_from_conic(conic_n))) if iterations else u
        try:  # compiled; numpy's complex eig when a reduced problem's eigenvalues are not real
            conic_n = reweighted_fit(u, v, arc, conic_n, iterations, CONVERGED)
        except np.linalg.LinAlgError as exc:
            raise EllipseFitError('points are degenerate (collinear or too few)') from exc
        except ValueError:
            conic_n = _reweighted_numpy(u, v, arc, conic_n, iterations)
        if not np.all(np.isfinite(conic_n)):
            raise EllipseFitError('no ellipse fits these points')
    conic = _denormalise(conic_n, mx, my, s)
    ell = ellipse_from_conic(conic)
    rms = float(np.sqrt(np.mean(sampson_distances(conic, p) ** 2)))
    return Ellipse(ell.center, ell.semi_axes, ell.angle, rms)
