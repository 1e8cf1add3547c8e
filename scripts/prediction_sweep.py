"""Try mode chains on the prediction suite: pooled NEES and the worst kind's coverage, 2 s ahead.

    .venv/bin/python scripts/prediction_sweep.py                 # the README's variants
    .venv/bin/python scripts/prediction_sweep.py --runs 10 CFG.json

A variant is a JSON object of :class:`activesurv_prediction.imm.ModeSet` fields (``rates`` as
the 3x3 off-diagonal rates, rows and columns S, CV, CA) and ``scale``, a factor on every
predicted covariance; ``{}`` is the shipped predictor. Two worker processes.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from multiprocessing import Pool
from pathlib import Path
from typing import Any

from activesurv_prediction import imm
from activesurv_prediction.base import Predictor
from activesurv_prediction.predictor import TargetPredictor
from activesurv_studies.prediction_suite import evaluate_suite

VARIANTS: list[dict[str, Any]] = [
    {},
    {'scale': 0.6},
    {'rates': [[0.0, 0.25, 0.05], [0.04, 0.0, 0.05], [0.04, 0.3, 0.0]]},
    {'acceleration_std': 0.008},
    {'rates': [[0.0, 0.25, 0.05], [0.02, 0.0, 0.15], [0.02, 0.3, 0.0]]},
    {'lateral_acceleration_std': 0.001},
    {
        'rates': [[0.0, 0.25, 0.05], [0.04, 0.0, 0.05], [0.04, 0.3, 0.0]],
        'acceleration_std': 0.008,
        'lateral_acceleration_std': 0.001,
    },
]


class Scaled(TargetPredictor):
    """The predictor with its covariances multiplied by ``scale``."""

    def __init__(self, scale: float, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.scale = scale

    def predict_many(self, times: Any) -> list[tuple[Any, Any]]:
        return [(m, self.scale * c) for m, c in super().predict_many(times)]


def evaluate(job: tuple[dict[str, Any], int]) -> dict[str, Any]:
    variant, runs = job
    fields = dict(variant)
    scale = float(fields.pop('scale', 1.0))
    if 'rates' in fields:
        fields['rates'] = imm.generator(fields['rates'])
    modes = imm.ModeSet(**fields)

    def factory() -> Predictor:
        return Scaled(scale, measurement_std=0.5e-3, modes=modes)

    res = evaluate_suite(factory, runs=runs)
    cov = {k: v['2s']['inside_3sigma'] for k, v in res.items()}
    nees = {k: v['2s']['mean_nees'] for k, v in res.items()}
    worst = min(cov, key=lambda k: cov[k])
    return {
        'variant': variant,
        'pooled_nees': round(statistics.mean(nees.values()), 3),
        'worst_kind': worst,
        'worst_inside_3sigma': cov[worst],
        'nees': nees,
        'rms_line_mm': res['paper_line']['2s']['rms_error_mm'],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('variants', nargs='?', type=Path, help='JSON list of variants')
    parser.add_argument('--runs', type=int, default=20, help='paths per kind (default 20)')
    args = parser.parse_args(argv)
    variants = VARIANTS if args.variants is None else json.loads(args.variants.read_text())
    with Pool(2) as pool:
        for r in pool.imap(evaluate, [(v, args.runs) for v in variants]):
            print(
                f'{json.dumps(r["variant"])}: pooled NEES {r["pooled_nees"]:.2f}, worst '
                f'{r["worst_kind"]} {r["worst_inside_3sigma"]:.3f}, line RMS '
                f'{r["rms_line_mm"]:.2f} mm',
                flush=True,
            )
    return 0


if __name__ == '__main__':
    sys.exit(main())
