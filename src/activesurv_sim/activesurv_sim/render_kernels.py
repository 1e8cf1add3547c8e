"""The renderer's coverage of a plain or disc plate over its box, compiled (numba).

:meth:`activesurv_sim.render.Renderer._cover` cuts a plate's box into tiles, fills the uniform
ones from their centre's ray and ray-casts the pixels of the others. Written as numpy array
operations it made some thirty temporary arrays of the boundary pixels a plate, and gathered
their rays through index arrays: on a loaded machine (four lab cameras rendering at 30 Hz beside
the graph) half of a frame's render. Here each pixel is one pass of a loop.

The arithmetic is :class:`activesurv_sim.render._PlateFrame`'s, operation for operation in
float32, so the frames are the same bit for bit
(``test_the_compiled_cover_is_the_array_codes_bit_for_bit``): the ray's components through
the plate's axes are accumulated as numpy's float32 matrix product accumulates them on this
machine (the first product, then two fused multiply-adds, emulated exactly in float64), and a
NaN propagates through minima and clips as numpy's do. Checkerboards (commissioning) stay in
numpy.

Compiled once per machine and cached beside this file (numba's ``cache=True``): ``make setup``
does it (:func:`warm_up`); a fresh clone's first call compiles (~3 s).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

F = TypeVar('F', bound=Callable[..., Any])
Real = float | np.floating[Any]  # a float32 inside the kernels
F32 = np.float32
_ZERO, _ONE, _HALF = F32(0.0), F32(1.0), F32(0.5)
_EPS = F32(1e-12)
FAR = F32(1e3)  # plate coordinate (m) given to rays that miss a plate's plane


def _compiled(f: F) -> F:
    """``numba.njit``, cached, GIL released; IEEE division (x / 0 is inf, as in numpy)."""
    return cast(F, numba.njit(cache=True, nogil=True, error_model='numpy')(f))


@_compiled
def _ramp(s: Real) -> Real:
    """Fraction of a pixel inside a boundary at signed distance ``s`` px (numpy's clip)."""
    x = _HALF - s
    if math.isnan(x):
        return x
    return min(max(x, _ZERO), _ONE)


@_compiled
def _fma(x: Real, y: Real, z: Real) -> Real:
    """x * y + z rounded once to float32 (the product of two float32 is exact in float64)."""
    return F32(np.float64(x) * np.float64(y) + np.float64(z))


@_compiled
def _nanmin(x: Real, y: Real) -> Real:
    """numpy's minimum: NaN if either is."""
    if math.isnan(x) or math.isnan(y):
        return x + y
    return min(x, y)


@_compiled
def _field(
    r0: Real,
    r1: Real,
    r2: Real,
    M: NDArray[np.float32],
    p: NDArray[np.float32],
    disc: bool,
) -> tuple[Real, Real, Real]:
    """Coverage, grey level and distance (px) to the nearest boundary of the ray (r0, r1, r2);
    ``p``: n0, a0, b0, 1/fx, 1/fy, half sizes, radius, plate level, mark level."""
    n0, a0, b0, fxi, fyi = p[0], p[1], p[2], p[3], p[4]
    h0, h1, radius, lo, hi = p[5], p[6], p[7], p[8], p[9]
    c0 = _fma(r2, M[2, 0], _fma(r1, M[1, 0], r0 * M[0, 0]))
    c1 = _fma(r2, M[2, 1], _fma(r1, M[1, 1], r0 * M[0, 1]))
    c2 = _fma(r2, M[2, 2], _fma(r1, M[1, 2], r0 * M[0, 2]))
    inv = _ONE / c0
    t = -n0 * inv
    valid = math.isfinite(t) and t > _ZERO
    if not valid:
        t = _ZERO
    ka = c1 * inv if valid else _ZERO
    kb = c2 * inv if valid else _ZERO
    a = a0 + t * c1 if valid else FAR
    b = b0 + t * c2 if valid else FAR
    tu, tv = t * fxi, t * fyi
    dau = tu * (M[0, 1] - ka * M[0, 0])
    dav = tv * (M[1, 1] - ka * M[1, 0])
    dbu = tu * (M[0, 2] - kb * M[0, 0])
    dbv = tv * (M[1, 2] - kb * M[1, 0])
    ga = F32(math.sqrt(dau * dau + dav * dav)) + _EPS
    gb = F32(math.sqrt(dbu * dbu + dbv * dbv)) + _EPS
    sa = (abs(a) - h0) / ga
    sb = (abs(b) - h1) / gb
    cov = _ramp(sa) * _ramp(sb) if valid else _ZERO
    near = _nanmin(abs(sa), abs(sb)) if valid else _ZERO
    mark: Real = _ZERO
    if disc:
        rho = F32(math.sqrt(a * a + b * b)) + _EPS
        gx = (a * dau + b * dbu) / rho
        gy = (a * dav + b * dbv) / rho
        sd = (rho - radius) / (F32(math.sqrt(gx * gx + gy * gy)) + _EPS)
        mark = _ramp(sd)
        near = _nanmin(near, abs(sd))
    return cov, lo + (hi - lo) * mark, near


@_compiled
def cover(
    rays: NDArray[np.float32],
    box: NDArray[np.int64],
    M: NDArray[np.float32],
    p: NDArray[np.float32],
    disc: bool,
    tile: int,
    uniform_px: Real,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Coverage and grey level of a plain or disc plate over ``box`` (u0, u1, v0, v1) of the
    camera's per-pixel rays (H, W, 3); ``M``, ``p``: the plate in the camera's frame
    (:meth:`activesurv_sim.render._PlateFrame.kernel_parameters`). A tile whose centre is more
    than ``uniform_px`` from every boundary is filled from its centre."""
    u0, u1, v0, v1 = box[0], box[1], box[2], box[3]
    hb, wb = v1 - v0, u1 - u0
    cov = np.empty((hb, wb), np.float32)
    lev = np.empty((hb, wb), np.float32)
    for i in range(-(-hb // tile)):
        cv = min(i * tile + tile // 2, hb - 1) + v0
        ve = min((i + 1) * tile, hb)
        for j in range(-(-wb // tile)):
            cu = min(j * tile + tile // 2, wb - 1) + u0
            ue = min((j + 1) * tile, wb)
            c, lv, near = _field(rays[cv, cu, 0], rays[cv, cu, 1], rays[cv, cu, 2], M, p, disc)
            if near > uniform_px:
                cov[i * tile : ve, j * tile : ue] = c
                lev[i * tile : ve, j * tile : ue] = lv
                continue
            for y in range(i * tile, ve):
                for x in range(j * tile, ue):
                    r = rays[y + v0, x + u0]
                    cov[y, x], lev[y, x], _ = _field(r[0], r[1], r[2], M, p, disc)
    return cov, lev


def warm_up() -> float:
    """Compile :func:`cover` (or load it from numba's cache) with the types the renderer calls
    it with: seconds taken."""
    start = time.perf_counter()
    rays = np.zeros((4, 4, 3), np.float32)
    rays[..., 2] = 1.0
    p = np.array([-1.0, 0.0, 0.0, 1e-3, 1e-3, 0.06, 0.06, 0.01, 25.0, 230.0], np.float32)
    M = np.eye(3, dtype=np.float32)
    for disc in (True, False):
        cover(rays, np.array([0, 4, 0, 4], np.int64), M, p, disc, 8, F32(12.0))
    return time.perf_counter() - start
