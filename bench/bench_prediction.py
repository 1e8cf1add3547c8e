"""Prediction benchmarks: 2-s-ahead accuracy and consistency, and the cost of one update.

Trajectories of the paper's kind: 20 random straight lines and 20 random parabolas inside the
500 x 200 mm table, traversed at a constant path speed of 10-20 mm/s, sampled at 30 Hz with
0.5 mm (std) noise on each overhead fix. After 2 s of tracking, every fix is followed by a
prediction 2 s ahead, compared with the true position then.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from activesurv_prediction.demands import DemandSchedule, TargetGeometry, predict_demands
from activesurv_prediction.predictor import TargetPredictor

Path2 = Callable[[float], np.ndarray]


def _by_arc_length(xs: np.ndarray, ys: np.ndarray, speed: float) -> Path2:
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xs), np.diff(ys)))])

    def f(t: float) -> np.ndarray:
        return np.array([np.interp(speed * t, s, xs), np.interp(speed * t, s, ys)])

    return f


def random_line(rng: np.random.Generator) -> tuple[Path2, float]:
    a = np.array([rng.uniform(0.02, 0.2), rng.uniform(0.02, 0.18)])
    b = np.array([rng.uniform(0.3, 0.48), rng.uniform(0.02, 0.18)])
    u = np.linspace(0.0, 1.0, 2000)
    speed = rng.uniform(0.01, 0.02)
    return _by_arc_length(a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), speed), float(
        np.linalg.norm(b - a) / speed
    )


def random_parabola(rng: np.random.Generator) -> tuple[Path2, float]:
    x0, x1 = rng.uniform(0.02, 0.12), rng.uniform(0.38, 0.48)
    depth = rng.uniform(0.04, 0.16) * rng.choice([-1.0, 1.0])
    xm = 0.5 * (x0 + x1)
    c = depth / (0.5 * (x1 - x0)) ** 2
    xs = np.linspace(x0, x1, 4000)
    y_base = 0.1 - depth / 2
    ys = y_base + c * (xs - xm) ** 2 - 0.0
    ys = np.clip(ys, 0.0, 0.2)
    speed = rng.uniform(0.01, 0.02)
    length = float(np.sum(np.hypot(np.diff(xs), np.diff(ys))))
    return _by_arc_length(xs, ys, speed), length / speed


def _evaluate(
    make: Callable[[np.random.Generator], tuple[Path2, float]], rng: np.random.Generator, n: int
) -> dict[str, float]:
    errs, inside = [], []
    for _ in range(n):
        path, duration = make(rng)
        p = TargetPredictor()
        for k in range(int(duration * 30)):
            t = k / 30.0
            p.update(t, path(t) + rng.normal(0.0, 0.5e-3, 2))
            if t >= 2.0 and t + 2.0 <= duration:
                m, c = p.predict(t + 2.0)
                e = m - path(t + 2.0)
                errs.append(float(np.linalg.norm(e)))
                inside.append(float(e @ np.linalg.solve(c, e)) <= 9.0)
    return {
        'rms_error_2s_mm': round(1e3 * math.sqrt(float(np.mean(np.square(errs)))), 3),
        'p95_error_2s_mm': round(1e3 * float(np.percentile(errs, 95)), 3),
        'inside_3sigma_fraction': round(float(np.mean(inside)), 4),
        'predictions': len(errs),
    }


def run() -> dict[str, Any]:
    rng = np.random.default_rng(11)
    out: dict[str, Any] = {}
    lines = _evaluate(random_line, rng, 20)
    parabolas = _evaluate(random_parabola, rng, 20)
    out['lines'] = lines
    out['parabolas'] = parabolas
    out['rms_2s_line_mm'] = lines['rms_error_2s_mm']
    out['rms_2s_parabola_mm'] = parabolas['rms_error_2s_mm']
    out['inside_3sigma_line'] = lines['inside_3sigma_fraction']
    out['inside_3sigma_parabola'] = parabolas['inside_3sigma_fraction']

    schedule = DemandSchedule.regular(0.0, 0.5, 400)
    geometry = TargetGeometry.create([0.0, -0.03, -0.03], [0.0, -1.0, 0.0])
    p = TargetPredictor()
    samples = []
    for k in range(3000):
        t = k / 30.0
        z = np.array([0.1 + 0.015 * t, 0.1]) + rng.normal(0.0, 0.5e-3, 2)
        t0 = time.perf_counter()
        p.update(t, z)
        predict_demands(p, schedule, geometry, 0.08, t, 10)
        samples.append(time.perf_counter() - t0)
    out['update_and_horizon_m10_ms'] = round(1e3 * statistics.median(samples[100:]), 4)
    return out
