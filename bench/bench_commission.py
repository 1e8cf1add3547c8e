"""Commissioning benchmarks (``commission.*``): over perturbed rigs (seeds 1..N, N = 10 or
``ACTIVESURV_COMMISSION_RIGS``), each camera commissioned by the procedure of
``activesurv commission`` on rendered views (``commission_offline``: the same looks, stations
and fits, without the node graph), each estimate against the rig; then the fast system's Set A
in lockstep on each rig told the commissioned calibration, the nominal values, or the truth.
"""

from __future__ import annotations

import dataclasses
import math
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from activesurv_bringup.rig.commission import commission_offline
from activesurv_bringup.rig.rigs import RigChoice, nominal, resolve_calibration
from activesurv_evaluation.results import summary
from activesurv_sim.rig import Rig, perturb_rig


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return round(statistics.median(finite), 9) if finite else math.nan


def run() -> dict[str, Any]:
    rigs = int(os.environ.get('ACTIVESURV_COMMISSION_RIGS', '10'))
    per: dict[str, list[float]] = {}
    runs: dict[str, dict[str, list[float]]] = {}
    seconds = []
    pp_z: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, rigs + 1):
            rig = perturb_rig(nominal(), seed)
            t0 = time.perf_counter()
            cal, report = commission_offline(rig)
            seconds.append(time.perf_counter() - t0)
            for cam in report['cameras'].values():
                per.setdefault('reprojection_rms_px', []).append(cam['reprojection_rms_px'])
                for key, value in cam['error'].items():
                    if key not in ('principal_point_x_px', 'principal_point_y_px'):  # signed
                        per.setdefault(key, []).append(value)
                # the procedure's own uncertainty, and whether the errors stay inside it
                sx, sy = cam['std']['principal_point_px']
                dx, dy = cam['error']['principal_point_x_px'], cam['error']['principal_point_y_px']
                per.setdefault('principal_point_std_x_px', []).append(sx)
                per.setdefault('principal_point_std_y_px', []).append(sy)
                pp_z.extend([abs(dx) / sx, abs(dy) / sy])
            per.setdefault('overhead_table_mapping_m', []).append(
                report['overhead']['error']['table_mapping_m']
            )
            choices = {
                'commissioned': RigChoice(rig, f'seed {seed}', cal, 'commissioned'),
                'nominal': RigChoice(
                    rig, f'seed {seed}', resolve_calibration('nominal', rig), 'nominal'
                ),
                'truth': RigChoice(rig, f'seed {seed}', rig.truth(), 'truth'),
            }
            for name, choice in choices.items():
                out = Path(tmp) / f'{seed}_{name}'
                doc = _lockstep(out, seed, choice)
                s = summary(doc)
                r = runs.setdefault(name, {'position': [], 'orientation': [], 'estimates': []})
                r['position'].append(s['median_position_error'])
                r['orientation'].append(s['median_orientation_error'])
                r['estimates'].append(s['estimates'])
            print(f'  commission: rig {seed} of {rigs} ({seconds[-1]:.0f} s)', flush=True)
    out: dict[str, Any] = {'rigs': rigs, 'seconds_per_rig': round(statistics.median(seconds), 1)}
    out['principal_point_within_3_std'] = round(sum(z <= 3.0 for z in pp_z) / len(pp_z), 3)
    # what the views carry with nothing but the corner finder's scatter: rig 1 made ideal
    _, ideal = commission_offline(ideal_rig(perturb_rig(nominal(), 1)))
    stds = [c['std']['principal_point_px'] for c in ideal['cameras'].values()]
    out['ideal_rig_principal_point_std_x_px'] = round(statistics.median(s[0] for s in stds), 3)
    out['ideal_rig_principal_point_std_y_px'] = round(statistics.median(s[1] for s in stds), 3)
    for key, values in per.items():
        out[f'median_{key}'] = _median(values)
        out[f'max_{key}'] = round(max(values), 9)
    for name, r in runs.items():
        out[f'set_a_fast_{name}_median_position_error_mm'] = round(1e3 * _median(r['position']), 4)
        out[f'set_a_fast_{name}_median_orientation_error_deg'] = round(
            math.degrees(_median(r['orientation'])), 4
        )
        out[f'set_a_fast_{name}_estimates'] = sum(r['estimates'])
    return out


def ideal_rig(rig: Rig) -> Rig:
    """``rig`` with exact stages and table (Table I accuracy set to zero)."""
    cameras = {
        k: dataclasses.replace(c, linear_accuracy=0.0, rotary_accuracy=0.0)
        for k, c in rig.cameras.items()
    }
    return dataclasses.replace(rig, table_accuracy=(0.0, 0.0), cameras=cameras)


def _lockstep(out: Path, seed: int, choice: RigChoice) -> dict[str, Any]:
    from activesurv_bringup.experiments.experiment import load_experiment
    from activesurv_bringup.experiments.lockstep import run_lockstep
    from activesurv_evaluation.results import results_document

    exp = load_experiment('A', 'fast', seed, rig=choice)
    return results_document('A', 'fast', run_lockstep(exp), {'seed': seed})


__all__ = ['run']
