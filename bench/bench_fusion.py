"""Fusion benchmarks: speed of one 6-variable fusion, and accuracy with one faulty camera."""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

from activesurv_fusion.errors import NoConsensusError
from activesurv_fusion.pose_fusion import (
    PoseReading,
    fuse_poses,
    median_fusion,
    weighted_mean_fusion,
)

SIGMA_P, SIGMA_N = 0.3e-3, 4e-3
COV = np.diag([SIGMA_P**2] * 3 + [SIGMA_N**2] * 3)
TRUTH = np.array([0.2, 0.1, 0.04, 0.0, -1.0, 0.0])


def _readings(rng: np.random.Generator, bias_sigmas: float) -> list[PoseReading]:
    out = []
    for i in range(4):
        v = TRUTH + rng.normal(0, np.sqrt(np.diag(COV)))
        if i == 1:
            v[0] += bias_sigmas * SIGMA_P
        out.append(PoseReading.create(f'cam{i + 1}', v[:3], v[3:], COV))
    return out


def run() -> dict[str, Any]:
    rng = np.random.default_rng(7)
    sets = [_readings(rng, 0.0) for _ in range(200)]
    for r in sets[:20]:
        fuse_poses(r)  # warm-up
    samples = []
    for r in sets * 5:
        t0 = time.perf_counter()
        fuse_poses(r)
        samples.append(time.perf_counter() - t0)
    out: dict[str, Any] = {'fuse_us_k4': round(1e6 * statistics.median(samples), 2)}

    errs: dict[str, list[float]] = {'optimal_region': [], 'weighted_mean': [], 'median': []}
    flagged = 0
    no_consensus = 0
    trials = 2000
    for _ in range(trials):
        r = _readings(rng, 5.0)
        try:
            f = fuse_poses(r)
        except NoConsensusError:
            no_consensus += 1
            continue
        flagged += 'cam2' in f.cameras_faulty
        errs['optimal_region'].append(float(np.linalg.norm(f.position - TRUTH[:3])))
        errs['weighted_mean'].append(
            float(np.linalg.norm(weighted_mean_fusion(r)[:3] - TRUTH[:3]))
        )
        errs['median'].append(float(np.linalg.norm(median_fusion(r)[:3] - TRUTH[:3])))
    out['faulty_5sigma'] = {
        'trials': trials,
        'camera_sigma_mm': SIGMA_P * 1e3,
        'bias_mm': 5 * SIGMA_P * 1e3,
        'faulty_camera_flagged_fraction': round(flagged / (trials - no_consensus), 4),
        'no_consensus_fraction': round(no_consensus / trials, 4),
        'median_position_error_mm': {
            k: round(1e3 * statistics.median(v), 4) for k, v in errs.items()
        },
        'mean_position_error_mm': {
            k: round(1e3 * statistics.fmean(v), 4) for k, v in errs.items()
        },
    }
    return out
