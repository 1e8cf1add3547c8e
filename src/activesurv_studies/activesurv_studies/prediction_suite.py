"""The prediction suite: how far ahead predictors are right, and whether they say so honestly.

For each path kind of :data:`activesurv_sim.paths.SUITE_KINDS`, ``runs`` seeded paths are
tracked from 30 Hz overhead fixes with 0.5 mm noise; after ``warmup`` seconds, every
``every``-th fix is followed by predictions ``leads`` seconds ahead, compared with the truth.

Consistency: a predictor claims its error ``e`` is N(0, C); then ``d2 = e^T C^-1 e`` (the NEES)
is chi-square with 2 dof: inside the 1-, 2- and 3-sigma ellipses 39.3, 86.5 and 98.9 % of the
time, with mean 2. The mean NEES is taken per run (predictions of one run are correlated), and
its 95 % band is that of the mean of ``runs`` independent chi-square(2) variables.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.stats import chi2

from activesurv_prediction.base import Predictor
from activesurv_sim.paths import SUITE_KINDS, suite_path

CLAIMED = {1: 1.0 - math.exp(-0.5), 2: 1.0 - math.exp(-2.0), 3: 1.0 - math.exp(-4.5)}


def nees_band(runs: int) -> tuple[float, float]:
    """The 95 % band of the mean of ``runs`` chi-square(2) variables."""
    lo, hi = chi2.ppf([0.025, 0.975], 2 * runs) / runs
    return float(lo), float(hi)


def evaluate_kind(
    factory: Callable[[], Predictor],
    kind: str,
    runs: int = 20,
    seed: int = 11,
    leads: Sequence[float] = (2.0,),
    every: int = 1,
    warmup: float = 2.0,
    noise: float = 0.5e-3,
    rate: float = 30.0,
) -> dict[str, Any]:
    """Statistics of ``factory()``'s predictions on ``runs`` paths of ``kind``, per lead."""
    rng = np.random.default_rng([seed, SUITE_KINDS.index(kind)])
    per_lead: dict[float, dict[str, list[float]]] = {
        lead: {'err': [], 'd2': [], 'run_nees': []} for lead in leads
    }
    update_s: list[float] = []
    for _ in range(runs):
        path = suite_path(kind, rng)
        p = factory()
        run_d2: dict[float, list[float]] = {lead: [] for lead in leads}
        for k in range(int(path.duration * rate)):
            t = k / rate
            z = path.position(t) + rng.normal(0.0, noise, 2)
            t0 = time.perf_counter()
            p.update(t, z)
            update_s.append(time.perf_counter() - t0)
            if t < warmup or k % every:
                continue
            ahead = [lead for lead in leads if t + lead <= path.duration]
            if not ahead:
                continue
            for lead, (m, c) in zip(ahead, p.predict_many([t + a for a in ahead]), strict=True):
                e = m - path.position(t + lead)
                d2 = float(e @ np.linalg.solve(c, e))
                per_lead[lead]['err'].append(float(np.hypot(*e)))
                per_lead[lead]['d2'].append(d2)
                run_d2[lead].append(d2)
        for lead in leads:
            if run_d2[lead]:
                per_lead[lead]['run_nees'].append(float(np.mean(run_d2[lead])))
    out: dict[str, Any] = {'runs': runs, 'update_us_median': 1e6 * float(np.median(update_s))}
    for lead, v in per_lead.items():
        err, d2s = np.array(v['err']), np.array(v['d2'])
        band = nees_band(len(v['run_nees']))
        nees = float(np.mean(v['run_nees']))
        out[f'{lead:g}s'] = {
            'predictions': len(err),
            'rms_error_mm': round(1e3 * math.sqrt(float(np.mean(err**2))), 3),
            'p95_error_mm': round(1e3 * float(np.percentile(err, 95)), 3),
            'inside_1sigma': round(float(np.mean(d2s <= 1.0)), 4),
            'inside_2sigma': round(float(np.mean(d2s <= 4.0)), 4),
            'inside_3sigma': round(float(np.mean(d2s <= 9.0)), 4),
            'mean_nees': round(nees, 3),
            'nees_band_95': [round(band[0], 3), round(band[1], 3)],
            'nees_in_band': bool(band[0] <= nees <= band[1]),
        }
    return out


def evaluate_suite(
    factory: Callable[[], Predictor],
    kinds: Sequence[str] = SUITE_KINDS,
    progress: Callable[[str], None] | None = None,
    **kwargs: Any,
) -> dict[str, dict[str, Any]]:
    """:func:`evaluate_kind` for each kind."""
    out = {}
    for kind in kinds:
        out[kind] = evaluate_kind(factory, kind, **kwargs)
        if progress is not None:
            progress(kind)
    return out
