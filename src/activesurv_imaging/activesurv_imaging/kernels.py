"""The edge measurement's per-edge loops, compiled (numba).

Each edge of a marker is one grey-level profile across the boundary: a few dozen samples,
the marker's and the plate's levels from its ends, and a crossing or an area. Written as numpy
array operations the work is small but spread over some sixty calls a frame, each paying its
overhead and its temporary arrays (the frame's edges took 4-5 ms, three times an OpenCV
pipeline's whole frame). Here each edge is one pass of a loop, its profile sampled from the
image as it goes.

Semantics are :mod:`activesurv_imaging.detect`'s (its docstrings say why each step is as it
is): profiles sampled bilinearly in linear radiance (the camera's response undone through a
256-entry table), the image's border replicated; levels are medians; a crossing is the first
sample below a level, searched from the inside outwards, linearly interpolated.

Compiled once per machine and cached beside this file (numba's ``cache=True``; where that is
not writable, in numba's user cache directory): a fresh clone's first call compiles (~2 s).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
F = TypeVar('F', bound=Callable[..., Any])


# Fast floating point without the flags that assume no NaN or infinity (a missing crossing is a
# NaN, and is tested for): sampling three times faster.
FASTMATH = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}


def _compiled(f: F) -> F:
    """``numba.njit`` with the cache on and the GIL released (imagers run beside each other)."""
    return cast(F, numba.njit(cache=True, nogil=True, fastmath=FASTMATH)(f))


@_compiled
def _bilinear(img: NDArray[np.uint8], lut: NDArray[np.float64], x: float, y: float) -> float:
    """Bilinear sample at (x, y) through ``lut``, (x, y) in [0, w - 1) x [0, h - 1)."""
    x0, y0 = int(x), int(y)
    fx, fy = x - x0, y - y0
    top = (1.0 - fx) * lut[img[y0, x0]] + fx * lut[img[y0, x0 + 1]]
    bottom = (1.0 - fx) * lut[img[y0 + 1, x0]] + fx * lut[img[y0 + 1, x0 + 1]]
    return float((1.0 - fy) * top + fy * bottom)


@_compiled
def _sample(img: NDArray[np.uint8], lut: NDArray[np.float64], x: float, y: float) -> float:
    """Bilinear sample at (x, y), the border replicated, through ``lut``."""
    h, w = img.shape
    # Clamped just inside the last pixel: its right-hand neighbour then always exists, and
    # truncation is the floor.
    x = min(max(x, 0.0), w - 1.0 - 1e-9)
    y = min(max(y, 0.0), h - 1.0 - 1e-9)
    return _bilinear(img, lut, x, y)


@_compiled
def _profile(
    img: NDArray[np.uint8],
    lut: Array,
    px: float,
    py: float,
    nx: float,
    ny: float,
    start: float,
    step: float,
    count: int,
    out: Array,
) -> None:
    """``count`` samples along (nx, ny) through (px, py), from ``start`` px on, ``step`` px
    apart, into ``out``; a profile that lies inside the image (most) without clamping each
    sample."""
    h, w = img.shape
    x0, y0 = px + nx * start, py + ny * start
    x1, y1 = x0 + nx * step * (count - 1), y0 + ny * step * (count - 1)
    hi_x, hi_y = w - 1.0 - 1e-9, h - 1.0 - 1e-9
    if not (
        min(x0, x1) >= 0.0 and max(x0, x1) <= hi_x and min(y0, y1) >= 0.0 and max(y0, y1) <= hi_y
    ):
        for j in range(count):
            d = start + j * step
            out[j] = _sample(img, lut, px + nx * d, py + ny * d)
        return
    dx, dy = nx * step, ny * step
    for j in range(count):
        out[j] = _bilinear(img, lut, x0 + j * dx, y0 + j * dy)


@_compiled
def _median(values: Array, start: int, stop: int, scratch: Array) -> float:
    """The median of ``values[start:stop]`` (a handful of samples: an insertion sort in
    ``scratch``; numpy's median allocates, which costs more than the sort; more than 32: a
    sort)."""
    n = stop - start
    if n > 32:  # more than a handful: numpy's sort
        ordered = np.sort(values[start:stop])
        if n % 2:
            return float(ordered[n // 2])
        return float(0.5 * (ordered[n // 2 - 1] + ordered[n // 2]))
    for j in range(n):
        v = values[start + j]
        k = j
        while k > 0 and scratch[k - 1] > v:
            scratch[k] = scratch[k - 1]
            k -= 1
        scratch[k] = v
    if n % 2:
        return float(scratch[n // 2])
    return float(0.5 * (scratch[n // 2 - 1] + scratch[n // 2]))


@_compiled
def _crossing(level: Array, n: int, start: float, step: float, at: float) -> float:
    """Where ``level[:n]`` (samples ``start + j step``) first falls below ``at`` from the
    inside outwards, interpolated; NaN if it never does or starts below."""
    for j in range(n):
        if level[j] < at:
            if j == 0:
                return math.nan
            v0, v1 = level[j - 1], level[j]
            frac = min(max((v0 - at) / max(v0 - v1, 1e-9), 0.0), 1.0)
            return float(start + (j - 1) * step + step * frac)
    return math.nan


@_compiled
def first_pass(
    img: NDArray[np.uint8],
    lut: Array,
    points: Array,
    normals: Array,
    half: float,
    step: float,
    min_contrast: float,
) -> tuple[Array, Array]:
    """Each edge's half-way crossing on a profile of ``half`` px either side of its boundary
    point (samples ``step`` apart), the levels the medians of its inner and outer quarters.

    Returns the offsets along the normals (px; NaN where the contrast is below
    ``min_contrast`` or there is no crossing) and each such edge's squared blur sigma from its
    25 % and 75 % crossings (px^2; NaN where one is missing).
    """
    n = points.shape[0]
    s = math.ceil((2.0 * half + 1e-9) / step)
    quarter = max(s // 4, 1)
    t = np.full(n, np.nan)
    sig2 = np.full(n, np.nan)
    prof = np.empty(s)
    level = np.empty(s)
    scratch = np.empty(quarter)
    for i in range(n):
        px, py, nx, ny = points[i, 0], points[i, 1], normals[i, 0], normals[i, 1]
        _profile(img, lut, px, py, nx, ny, -half, step, s, prof)
        bright = _median(prof, 0, quarter, scratch)
        dark = _median(prof, s - quarter, s, scratch)
        if bright - dark < min_contrast:
            continue
        mid = 0.5 * (bright + dark)
        c = _crossing(prof, s, -half, step, mid)
        if math.isnan(c):
            continue
        t[i] = c
        span = max(bright - dark, 1e-9)
        for j in range(s):
            level[j] = (prof[j] - dark) / span
        sigma = (
            _crossing(level, s, -half, step, 0.25) - _crossing(level, s, -half, step, 0.75)
        ) / 1.349
        sig2[i] = sigma * sigma
    return t, sig2


@_compiled
def window_pass(
    img: NDArray[np.uint8],
    lut: Array,
    points: Array,
    normals: Array,
    halves: Array,
    margin: float,
    area: bool,
    min_contrast: float,
) -> tuple[Array, NDArray[np.bool_]]:
    """Each edge again on a profile centred on it, ``halves[i]`` px either side (samples 0.25
    px apart up to 8 px, else 0.5), the levels the medians of its outer ``margin`` px at either
    end: the area-equivalent edge (``area``) or the half-way crossing.

    Returns the offsets (px) and which edges held (contrast at least ``min_contrast``, the
    edge inside the window less its margins).
    """
    n = points.shape[0]
    t = np.full(n, np.nan)
    keep = np.zeros(n, dtype=np.bool_)
    longest = 1
    for i in range(n):
        step = 0.25 if halves[i] <= 8.0 else 0.5
        longest = max(longest, math.ceil((2.0 * halves[i] + 1e-9) / step))
    prof = np.empty(longest)
    scratch = np.empty(longest)
    buf = np.empty(longest)
    for i in range(n):
        half = halves[i]
        step = 0.25 if half <= 8.0 else 0.5
        s = math.ceil((2.0 * half + 1e-9) / step)
        px, py, nx, ny = points[i, 0], points[i, 1], normals[i, 0], normals[i, 1]
        _profile(img, lut, px, py, nx, ny, -half, step, s, prof)
        k = 0  # samples at each end beyond the window's inner part (|d| > half - margin)
        while k < s and -half + k * step < -(half - margin):
            k += 1
        m = 0
        while m < s and -half + (s - 1 - m) * step > half - margin:
            m += 1
        if k == 0 or m == 0:
            continue
        # The levels from the margins' samples 0.5 px apart: closer ones interpolate the
        # same pixels again, and tell the median nothing more.
        thin = 2 if step < 0.5 else 1
        for j in range(0, k, thin):
            scratch[j // thin] = prof[j]
        bright = _median(scratch, 0, (k + thin - 1) // thin, buf)
        for j in range(s - m, s, thin):
            scratch[(j - (s - m)) // thin] = prof[j]
        dark = _median(scratch, 0, (m + thin - 1) // thin, buf)
        span = bright - dark
        scale = 1.0 / max(span, 1e-9)
        for j in range(s):
            prof[j] = (prof[j] - dark) * scale  # the level, 0 on the plate, 1 on the marker
        if area:  # the integral of the level over the window: its length inside the marker
            total = 0.0
            for j in range(s):
                total += prof[j]
            ti = step * (total - 0.5 * (prof[0] + prof[s - 1])) - half
        else:
            ti = _crossing(prof, s, -half, step, 0.5)
        t[i] = ti
        keep[i] = span >= min_contrast and abs(ti) < half - margin
    return t, keep


@_compiled
def scatter(u: Array, v: Array, w: Array) -> Array:
    """The weighted fit's scatter matrix ``D^T D`` (6 x 6), row i of D being
    ``w_i (u^2, uv, v^2, u, v, 1)`` (:func:`activesurv_imaging.ellipse.fit_ellipse`)."""
    s = np.zeros((6, 6))
    row = np.empty(6)
    for i in range(u.shape[0]):
        x, y, wi = u[i], v[i], w[i]
        row[0], row[1], row[2] = wi * x * x, wi * x * y, wi * y * y
        row[3], row[4], row[5] = wi * x, wi * y, wi
        for a in range(6):
            ra = row[a]
            for b in range(a, 6):
                s[a, b] += ra * row[b]
    for a in range(6):
        for b in range(a):
            s[a, b] = s[b, a]
    return s


@_compiled
def sampson_weights(u: Array, v: Array, arc: Array, conic: Array) -> Array:
    """Each point's weight ``arc_i / |grad Q(u_i, v_i)|`` under ``conic``, scaled to a largest
    of 1 (the re-weighting of :func:`activesurv_imaging.ellipse.fit_ellipse`)."""
    a, b, c, d, e = conic[0], conic[1], conic[2], conic[3], conic[4]
    n = u.shape[0]
    w = np.empty(n)
    top = 0.0
    for i in range(n):
        gx = 2.0 * a * u[i] + b * v[i] + d
        gy = b * u[i] + 2.0 * c * v[i] + e
        w[i] = arc[i] / max(math.sqrt(gx * gx + gy * gy), 1e-12)
        top = max(top, w[i])
    for i in range(n):
        w[i] /= top
    return w


@_compiled
def otsu(hist: Array) -> int:
    """Otsu's threshold of a 256-bin histogram, as OpenCV's ``THRESH_OTSU`` computes it (the
    same loop: the frame's histogram is then made once, for its levels and this)."""
    total = 0.0
    mu = 0.0
    for i in range(256):
        total += hist[i]
        mu += i * hist[i]
    if total <= 0.0:
        return 0
    scale = 1.0 / total
    mu *= scale
    eps = 1.1920928955078125e-07  # FLT_EPSILON
    q1 = 0.0
    mu1 = 0.0
    best = 0.0
    best_i = 0
    for i in range(256):
        p = hist[i] * scale
        mu1 *= q1
        q1 += p
        q2 = 1.0 - q1
        if min(q1, q2) < eps or max(q1, q2) > 1.0 - eps:
            continue
        mu1 = (mu1 + i * p) / q1
        mu2 = (mu - q1 * mu1) / q2
        sigma = q1 * q2 * (mu1 - mu2) * (mu1 - mu2)
        if sigma > best:
            best = sigma
            best_i = i
    return best_i


@_compiled
def _solve3(a: Array, b: Array) -> Array:
    """``a^-1 b`` for a symmetric 3 x 3 ``a`` (its adjugate: numpy's general solver takes
    numba five seconds to compile).

    Raises:
        numpy.linalg.LinAlgError: ``a`` singular to 1e-13 of its scale.
    """
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    scale = 0.0
    for i in range(3):
        for j in range(3):
            scale = max(scale, abs(a[i, j]))
    if not abs(det) > 1e-13 * scale**3:
        raise np.linalg.LinAlgError('singular matrix')
    inv = np.empty((3, 3))
    inv[0, 0], inv[1, 0], inv[2, 0] = c00, c01, c02
    inv[0, 1] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    inv[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    inv[2, 1] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    inv[0, 2] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    inv[1, 2] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    inv[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    out: Array = (inv / det) @ b
    return out


@_compiled
def direct_fit(u: Array, v: Array, w: Array) -> Array:
    """The weighted constrained conic fit (Halir-Flusser) of points (u, v) with weights w:
    the conic (6,) in those coordinates, NaN when no eigenvector is an ellipse.

    Raises:
        numpy.linalg.LinAlgError: degenerate points (the linear part's scatter is singular).
        ValueError: the reduced problem has complex eigenvalues (numba's ``eig`` stays real;
            :func:`activesurv_imaging.ellipse.fit_ellipse` then solves it with numpy's).
    """
    s = scatter(u, v, w)
    s1 = np.ascontiguousarray(s[:3, :3])
    s2 = np.ascontiguousarray(s[:3, 3:])
    s3 = np.ascontiguousarray(s[3:, 3:])
    t = -_solve3(s3, np.ascontiguousarray(s2.T))
    m = s1 + s2 @ t
    mm = np.empty((3, 3))
    for k in range(3):  # C1^-1 M
        mm[0, k] = m[2, k] / 2.0
        mm[1, k] = -m[1, k]
        mm[2, k] = m[0, k] / 2.0
    vals, vecs = np.linalg.eig(mm)
    best = -1
    for k in range(3):
        if 4.0 * vecs[0, k] * vecs[2, k] - vecs[1, k] ** 2 > 0.0 and (
            best < 0 or abs(vals[k]) < abs(vals[best])
        ):
            best = k
    out = np.full(6, np.nan)
    if best < 0:
        return out
    a1 = np.ascontiguousarray(vecs[:, best])
    out[:3] = a1
    out[3:] = t @ a1
    return out


@_compiled
def arc_weights(
    u: Array, v: Array, cx: float, cy: float, a: float, b: float, angle: float
) -> Array:
    """The arc length each point stands for around the ellipse (centre, semi-axes, angle):
    half the gap to each neighbour in angle order, at least a millionth of the median."""
    ca, sa = math.cos(angle), math.sin(angle)
    n = u.shape[0]
    phi = np.empty(n)
    for i in range(n):
        du, dv = u[i] - cx, v[i] - cy
        phi[i] = math.atan2((-sa * du + ca * dv) / b, (ca * du + sa * dv) / a)
    order = np.argsort(phi)
    gap = np.empty(n)
    for k in range(n):
        i, j = order[k], order[(k + 1) % n]
        gap[k] = math.hypot(u[j] - u[i], v[j] - v[i])
    s = np.empty(n)
    for k in range(n):
        s[order[k]] = 0.5 * (gap[k] + gap[k - 1])  # gap[-1]: the last point's, round to it
    floor = 1e-6 * max(_median(s, 0, n, np.empty(n)), 1e-12)
    for i in range(n):
        s[i] = max(s[i], floor)
    return s


@_compiled
def ellipse_parameters(A: float, B: float, C: float, D: float, E: float, F: float) -> Array:
    """Centre, semi-axes and angle of the conic's ellipse, ``4AC - B^2 > 0`` given:
    (cx, cy, a, b, angle), all NaN for an imaginary or degenerate one
    (:func:`activesurv_imaging.ellipse.ellipse_from_conic`)."""
    out = np.full(5, np.nan)
    disc = 4.0 * A * C - B * B
    cx = (-2.0 * C * D + B * E) / disc
    cy = (B * D - 2.0 * A * E) / disc
    f0 = F + 0.5 * (D * cx + E * cy)  # Q at the centre
    q = np.empty((2, 2))
    q[0, 0], q[0, 1], q[1, 0], q[1, 1] = A, B / 2.0, B / 2.0, C
    mu, vecs = np.linalg.eigh(q)
    if f0 == 0.0 or -f0 / mu[0] <= 0.0 or -f0 / mu[1] <= 0.0:
        return out
    r0, r1 = -f0 / mu[0], -f0 / mu[1]  # squared semi-axis along each eigenvector
    major = 0 if r0 >= r1 else 1
    out[0], out[1] = cx, cy
    out[2], out[3] = math.sqrt(max(r0, r1)), math.sqrt(min(r0, r1))
    out[4] = math.atan2(vecs[1, major], vecs[0, major]) % math.pi
    return out


@_compiled
def sampson(conic: Array, points: Array) -> Array:
    """Each point's first-order geometric distance ``|Q| / |grad Q|`` to the conic (px)."""
    A, B, C, D, E, F = conic[0], conic[1], conic[2], conic[3], conic[4], conic[5]
    n = points.shape[0]
    out = np.empty(n)
    for i in range(n):
        x, y = points[i, 0], points[i, 1]
        q = A * x * x + B * x * y + C * y * y + D * x + E * y + F
        gx = 2.0 * A * x + B * y + D
        gy = B * x + 2.0 * C * y + E
        out[i] = abs(q) / max(math.sqrt(gx * gx + gy * gy), 1e-300)
    return out


@_compiled
def outward_normals(conic: Array, cx: float, cy: float, points: Array) -> Array:
    """The conic's unit gradient at each point, turned to point away from (cx, cy)."""
    A, B, C, D, E = conic[0], conic[1], conic[2], conic[3], conic[4]
    n = points.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        x, y = points[i, 0], points[i, 1]
        gx = 2.0 * A * x + B * y + D
        gy = B * x + 2.0 * C * y + E
        norm = max(math.sqrt(gx * gx + gy * gy), 1e-12)
        gx, gy = gx / norm, gy / norm
        if gx * (x - cx) + gy * (y - cy) < 0.0:
            gx, gy = -gx, -gy
        out[i, 0], out[i, 1] = gx, gy
    return out


@_compiled
def evenly_spaced(
    at: Array, cx: float, cy: float, a: float, b: float, angle: float, count: int
) -> tuple[Array, Array, NDArray[np.intp]]:
    """``count`` points at evenly spaced parametric angles of the ellipse, those within 3 of
    ``at``'s mean spacings of a point of ``at`` (a gap in ``at`` stays a gap): the points,
    their outward normals and for each the index of the point of ``at`` nearest in angle
    (:func:`activesurv_imaging.detect._off_the_grid`)."""
    ca, sa = math.cos(angle), math.sin(angle)
    n = at.shape[0]
    psi = np.empty(n)
    for i in range(n):
        dx, dy = at[i, 0] - cx, at[i, 1] - cy
        psi[i] = math.atan2((-sa * dx + ca * dy) / b, (ca * dx + sa * dy) / a)
    order = np.argsort(psi)
    ps = psi[order]
    turn = 2.0 * math.pi
    limit = 3.0 * (turn / n)
    pts = np.empty((count, 2))
    nrm = np.empty((count, 2))
    near = np.empty(count, dtype=np.intp)
    kept = 0
    j = 0  # the first of ps at or beyond the grid angle (the grid and ps both ascend)
    for k in range(count):
        g = -math.pi + (k + 0.5) * (turn / count)
        while j < n and ps[j] < g:
            j += 1
        jj = j % n
        ii = (jj - 1) % n
        gap_j = (ps[jj] - g) % turn
        gap_i = (g - ps[ii]) % turn
        if gap_i + gap_j > limit:
            continue
        near[kept] = order[jj] if gap_j < gap_i else order[ii]
        x, y = a * math.cos(g), b * math.sin(g)
        pts[kept, 0] = cx + ca * x - sa * y
        pts[kept, 1] = cy + sa * x + ca * y
        gx, gy = x / (a * a), y / (b * b)
        ux, uy = ca * gx - sa * gy, sa * gx + ca * gy
        norm = max(math.sqrt(ux * ux + uy * uy), 1e-12)
        nrm[kept, 0], nrm[kept, 1] = ux / norm, uy / norm
        kept += 1
    return pts[:kept], nrm[:kept], near[:kept]


@_compiled
def row_medians(rows: Array) -> Array:
    """Each row's median of its finite values (NaN for a row without any)."""
    r, c = rows.shape
    out = np.full(r, np.nan)
    buf = np.empty(c)
    scratch = np.empty(c)
    for i in range(r):
        n = 0
        for j in range(c):
            if math.isfinite(rows[i, j]):
                buf[n] = rows[i, j]
                n += 1
        if n:
            out[i] = _median(buf, 0, n, scratch)
    return out


@_compiled
def curvature(cx: float, cy: float, a: float, b: float, angle: float, points: Array) -> Array:
    """The ellipse's curvature (1/px) at the points of it nearest ``points`` by their angle."""
    ca, sa = math.cos(angle), math.sin(angle)
    n = points.shape[0]
    out = np.empty(n)
    for i in range(n):
        dx, dy = points[i, 0] - cx, points[i, 1] - cy
        phi = math.atan2((-sa * dx + ca * dy) / b, (ca * dx + sa * dy) / a)
        s, c = math.sin(phi), math.cos(phi)
        out[i] = a * b / (a * a * s * s + b * b * c * c) ** 1.5
    return out


def warm_up() -> float:
    """Compile every kernel (or load it from numba's cache) with the types the imager calls
    it with, so that no frame pays for it: seconds taken (~0.5 s from the cache; ~16 s to
    compile, once per machine and source: ``make setup`` does it)."""
    start = time.perf_counter()
    img = np.zeros((16, 16), dtype=np.uint8)
    lut = np.arange(256, dtype=np.float64)
    angle = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
    pts = np.ascontiguousarray(
        np.column_stack([8.0 + 4.0 * np.cos(angle), 8.0 + 3.0 * np.sin(angle)])
    )
    nrm = np.ascontiguousarray(np.column_stack([np.cos(angle), np.sin(angle)]))
    u, v, w = pts[:, 0] - 8.0, pts[:, 1] - 8.0, np.ones(len(angle))
    conic = np.array([1.0 / 16.0, 0.0, 1.0 / 9.0, 0.0, 0.0, -1.0])
    frozen = img.copy()
    frozen.setflags(write=False)  # a frame straight from a message buffer: another type
    for image in (img, frozen):
        first_pass(image, lut, pts, nrm, 4.0, 0.25, 40.0)
        window_pass(image, lut, pts, nrm, np.full(len(angle), 5.0), 4.0, True, 40.0)
    direct_fit(np.ascontiguousarray(u), np.ascontiguousarray(v), w)
    reweighted_fit(np.ascontiguousarray(u), np.ascontiguousarray(v), w, conic, 2, 1e-7)
    sampson_weights(np.ascontiguousarray(u), np.ascontiguousarray(v), w, conic)
    arc_weights(np.ascontiguousarray(u), np.ascontiguousarray(v), 0.0, 0.0, 4.0, 3.0, 0.0)
    ellipse_parameters(1.0 / 16.0, 0.0, 1.0 / 9.0, 0.0, 0.0, -1.0)
    sampson(conic, pts)
    otsu(np.ones(256))
    outward_normals(conic, 8.0, 8.0, pts)
    evenly_spaced(pts, 8.0, 8.0, 4.0, 3.0, 0.0, 16)
    row_medians(np.ones((2, 4)))
    curvature(8.0, 8.0, 4.0, 3.0, 0.0, pts)
    return time.perf_counter() - start


@_compiled
def reweighted_fit(
    u: Array, v: Array, arc: Array, conic: Array, iterations: int, converged: float
) -> Array:
    """The fit re-weighted from ``conic`` at most ``iterations`` times, each point weighted by
    ``arc_i / |grad Q|`` of the previous conic, until the unit conic moves less than
    ``converged`` (:func:`activesurv_imaging.ellipse.fit_ellipse`): the last conic, NaN when a
    fit found no ellipse.

    Raises:
        numpy.linalg.LinAlgError, ValueError: as :func:`direct_fit`.
    """
    for _ in range(iterations):
        new = direct_fit(u, v, sampson_weights(u, v, arc, conic))
        if not np.isfinite(new[0]):
            return new
        dot = 0.0
        nn = 0.0
        nc = 0.0
        for k in range(6):
            dot += new[k] * conic[k]
            nn += new[k] * new[k]
            nc += conic[k] * conic[k]
        scale = (1.0 if dot > 0.0 else (-1.0 if dot < 0.0 else 0.0)) / math.sqrt(nn)
        moved = 0.0
        for k in range(6):
            new[k] *= scale
            moved += (new[k] - conic[k] / math.sqrt(nc)) ** 2
        conic = new
        if math.sqrt(moved) < converged:
            break
    return conic
