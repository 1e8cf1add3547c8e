"""Temporal calibration of a camera against a moving stage: its exposure delay and jitter.

A camera stamps each frame some time ``d`` after its exposure (exposure, read-out, transfer,
and whatever its clock is off by). Moving a target at known speeds in front of it and comparing
where the frames show the target with where the stage controller reported it (stamped on the
host's clock) gives ``d``, as camera-IMU calibrators find a camera's time offset:

    c_k = a + b x_k + e x_k^2,  x_k = x_table(s_k - d)     for each image coordinate c (u, v)

``s_k`` is frame ``k``'s stamp, ``x_table`` the controller's reports interpolated in time; the
image coordinates depend smoothly on the table position (a quadratic takes up perspective over a
sweep of a few centimetres), so for a given ``d`` the curve is a linear least-squares fit, and
``d`` is the one that fits best. Back and
forth passes at several speeds separate ``d`` from any static offset (the calibration's error
moves ``a``, not ``d``). The stamps' jitter is the spread of each frame's residual turned into
time: residual along the motion / (image speed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class DelayFit:
    """What a temporal calibration found.

    Attributes:
        delay: s from exposure to stamp (what the imager subtracts: ``exposure_delay``).
        jitter: s, robust std of the frames' stamps around it.
        samples: frames used.
        rms_px: the fit's residual (px).
        speed_px: median image speed of the target in the frames used (px/s).
    """

    delay: float
    jitter: float
    samples: int
    rms_px: float
    speed_px: float


class TemporalFitError(ValueError):
    """Too few usable frames, or a motion that does not determine the delay."""


def _interp(t: Array, x: Array, at: Array) -> Array:
    return np.interp(at, t, x, left=np.nan, right=np.nan)


def _residual(d: float, s: Array, uv: Array, t: Array, x: Array) -> tuple[float, Array, Array]:
    """Sum of squares of the best quadratic fit at delay ``d``, the residuals, and each
    frame's image displacement per metre of table (N, 2)."""
    xs = _interp(t, x, s - d)
    ok = np.isfinite(xs)
    if ok.sum() < 6:
        return math.inf, np.zeros((0, 2)), np.zeros((0, 2))
    # Centred and scaled: a well-conditioned fit whatever the table coordinates are.
    m, k = float(np.mean(xs[ok])), max(float(np.std(xs[ok])), 1e-9)
    z = (xs[ok] - m) / k
    A = np.c_[np.ones(ok.sum()), z, z * z]
    coef, *_ = np.linalg.lstsq(A, uv[ok], rcond=None)
    res = uv[ok] - A @ coef
    slope = (coef[1][None, :] + 2.0 * z[:, None] * coef[2][None, :]) / k
    return float(np.sum(res**2)), res, slope


def fit_delay(
    stamps: ArrayLike,
    uv: ArrayLike,
    table_t: ArrayLike,
    table_x: ArrayLike,
    max_delay: float = 0.25,
    min_delay: float = -0.05,
) -> DelayFit:
    """The delay that best explains where frames show the target, given the table's reports.

    Args:
        stamps: frame stamps (s, host clock), (N,).
        uv: the target's image position in each frame (px), (N, 2).
        table_t, table_x: the controller's reports: stamps (s, increasing) and positions (m).
        max_delay, min_delay: the search range (s).

    Raises:
        TemporalFitError: with fewer than 10 frames inside the reports, or a still target.
    """
    s = np.asarray(stamps, dtype=np.float64).reshape(-1)
    p = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    t = np.asarray(table_t, dtype=np.float64).reshape(-1)
    x = np.asarray(table_x, dtype=np.float64).reshape(-1)
    order = np.argsort(t)
    t, x = t[order], x[order]
    keep = np.isfinite(s) & np.all(np.isfinite(p), axis=1)
    s, p = s[keep], p[keep]
    if len(s) < 10:
        raise TemporalFitError(f'{len(s)} frames with the target: at least 10 are needed')
    if np.ptp(x) < 1e-3:
        raise TemporalFitError('the table did not move: no delay can be seen')
    grid = np.arange(min_delay, max_delay + 1e-12, 0.0005)
    costs = np.array([_residual(float(d), s, p, t, x)[0] for d in grid])
    if not np.isfinite(costs).any():
        raise TemporalFitError('no frame lies inside the table reports')
    i = int(np.nanargmin(costs))
    # Golden-section search in the bracket around the best grid point.
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    for _ in range(40):
        c1, c2 = b - g * (b - a), a + g * (b - a)
        if _residual(c1, s, p, t, x)[0] <= _residual(c2, s, p, t, x)[0]:
            b = c2
        else:
            a = c1
    d = 0.5 * (a + b)
    cost, res, slope = _residual(d, s, p, t, x)
    n = len(res)
    # Each frame's residual along the image motion, in time: residual / image speed.
    xs = _interp(t, x, s - d)
    ok = np.isfinite(xs)
    vx = np.gradient(x, t)
    v = _interp(t, vx, s - d)[ok]
    norm = np.maximum(np.linalg.norm(slope, axis=1), 1e-12)
    img_speed = np.abs(v) * norm
    along = np.sum(res * slope, axis=1) / norm
    moving = img_speed > 0.5 * float(np.max(img_speed)) if n else np.zeros(0, bool)
    dt = along[moving] / img_speed[moving]
    jitter = float(1.4826 * np.median(np.abs(dt - np.median(dt)))) if dt.size else math.nan
    return DelayFit(
        float(d),
        jitter,
        n,
        float(math.sqrt(cost / max(n, 1))),
        float(np.median(img_speed[moving])) if moving.any() else 0.0,
    )


def delay_from_passes(fits: Sequence[DelayFit]) -> DelayFit:
    """One figure from several fits (cameras seen in several sweeps): sample-weighted."""
    if not fits:
        raise TemporalFitError('no fit')
    w = np.array([f.samples for f in fits], dtype=np.float64)
    return DelayFit(
        float(np.average([f.delay for f in fits], weights=w)),
        float(np.average([f.jitter for f in fits], weights=w)),
        int(w.sum()),
        float(np.average([f.rms_px for f in fits], weights=w)),
        float(np.average([f.speed_px for f in fits], weights=w)),
    )
