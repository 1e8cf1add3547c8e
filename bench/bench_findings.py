"""The paper's findings over perturbed rigs (``findings.*``): the six experiments in lockstep on
20 rigs (the nominal rig perturbed with seeds 1-20, or ``ACTIVESURV_FINDINGS_RIGS``), each run
with the rig's own seed, the system told the rig's truth (commissioning lands within 5 % of it,
``commission.*``; this keeps the benchmark to minutes). Does fast > medium > static hold in both
sets, and does Set B start below Set A and recover within three demands, fast no later than
medium?
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from activesurv_evaluation.results import recovery_demand

SYSTEMS = ('static', 'medium', 'fast')


def _one(args: tuple[str, str, int]) -> list[float]:
    from activesurv_bringup.experiments.experiment import load_experiment
    from activesurv_bringup.experiments.lockstep import run_lockstep
    from activesurv_bringup.rig.choice import choose

    set_name, system, seed = args
    exp = load_experiment(set_name, system, seed, rig=choose(None, 'truth', seed))
    return [float(r.visibility) for r in run_lockstep(exp)]


def run() -> dict[str, Any]:
    rigs = int(os.environ.get('ACTIVESURV_FINDINGS_RIGS', '20'))
    jobs = [
        (s, system, seed) for seed in range(1, rigs + 1) for s in ('A', 'B') for system in SYSTEMS
    ]
    with ProcessPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
        curves = list(pool.map(_one, jobs))
    by: dict[tuple[str, str, int], list[float]] = dict(zip(jobs, curves, strict=True))
    out: dict[str, Any] = {'rigs': rigs}
    order_holds = {'A': 0, 'B': 0}
    dips = {'medium': 0, 'fast': 0}
    within3 = {'medium': 0, 'fast': 0}
    fast_first = 0
    for seed in range(1, rigs + 1):
        mean = {(s, x): float(np.mean(by[(s, x, seed)])) for s in ('A', 'B') for x in SYSTEMS}
        for s in ('A', 'B'):
            order_holds[s] += mean[(s, 'fast')] > mean[(s, 'medium')] > mean[(s, 'static')]
        rec = {}
        for x in ('medium', 'fast'):
            a, b = by[('A', x, seed)], by[('B', x, seed)]
            dips[x] += b[0] < a[0]
            rec[x] = recovery_demand(b, a)
            within3[x] += rec[x] <= 3
        fast_first += rec['fast'] <= rec['medium']
    out['fast_beats_medium_beats_static_A_rigs'] = f'{order_holds["A"]}/{rigs}'
    out['fast_beats_medium_beats_static_B_rigs'] = f'{order_holds["B"]}/{rigs}'
    for x in ('medium', 'fast'):
        out[f'set_B_{x}_starts_below_A_rigs'] = f'{dips[x]}/{rigs}'
        out[f'set_B_{x}_recovers_within_3_rigs'] = f'{within3[x]}/{rigs}'
    out['set_B_fast_no_later_than_medium_rigs'] = f'{fast_first}/{rigs}'
    out['mean_visibility_1e6'] = {
        f'{s}_{x}': round(
            float(np.mean([np.mean(by[(s, x, k)]) for k in range(1, rigs + 1)])) / 1e6, 1
        )
        for s in ('A', 'B')
        for x in SYSTEMS
    }
    out['first_demand_B_vs_A'] = {
        x: round(
            float(
                np.mean(
                    [
                        by[('B', x, k)][0] / max(by[('A', x, k)][0], 1e-9)
                        for k in range(1, rigs + 1)
                    ]
                )
            ),
            3,
        )
        for x in SYSTEMS
    }
    return out
