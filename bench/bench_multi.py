"""Several objects at once with an obstacle (``multi.*``), at real time.

``activesurv surveil --objects-at-once N`` on the nominal rig with one post in the cell (a
cylinder, r = 15 mm, 100 mm high, standing between the cameras and the middle of the table),
the system told the rig itself (errors are the method's), for ``ACTIVESURV_BENCH_MULTI_S``
simulated seconds (600 by default: the issue's 10 minutes) at rtf 1:

* ``two_ok_fraction`` / ``three_ok_fraction``: demands answered ``ok``;
* ``two_cameras_per_demand``: mean cameras assigned per demand;
* ``two_not_occluded_fraction``: demands whose assigned cameras all saw the marker unblocked
  (``occluded`` empty);
* ``two_id_switches``, ``two_gospa_mean_mm``, ``two_max_objects_at_once``;
* ``two_cameras_vs_clairvoyant`` / ``two_visibility_vs_clairvoyant``: cameras per demand and
  mean fused visibility against a clairvoyant dispatcher (knows the true positions and
  occlusions; ``activesurv_studies.clairvoyant``), and
  ``two_greedy_visibility_vs_clairvoyant`` for an occlusion-blind greedy one;
* ``two_latency_median_ms``: demand instant to estimate;
* ``scaling_<N>obj_<n>cam_cameras_per_demand`` / ``_none_fraction`` / ``_demands``: where it
  breaks, N = 1..4 objects at once with n = 4 or 8 cameras, in a dispatch lockstep (perfect
  predictions, no rendering; ``activesurv_studies.scaling``): assigned cameras that
  see the marker at the instant per demand, and the demands none sees;
* ``tracker_ms_per_frame_1`` / ``_3`` / ``_10``: the MultiTracker's time per overhead frame
  (gating, assignment, the IMM updates) with 1, 3 and 10 objects, and
  ``horizon_ms_per_frame_*`` the demand predictions after it (medians, this machine).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from activesurv_prediction.demands import TargetGeometry
from activesurv_prediction.multi import MultiTracker
from activesurv_studies.clairvoyant import compare
from activesurv_studies.scaling import run_scaling

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
SESSION_S = float(os.environ.get('ACTIVESURV_BENCH_MULTI_S', '600'))
SCALING_S = 120.0  # s of objects in each dispatch-lockstep run of the scaling study
POST = {'kind': 'cylinder', 'centre': [0.25, -0.2, 0.05], 'radius': 0.015, 'height': 0.1}


def _round(v: float | None) -> float | None:
    return None if v is None else round(float(v), 4)


def _session(tmp: Path, n: int) -> tuple[dict[str, Any], Path]:
    rig = tmp / 'rig.yaml'
    if not rig.exists():
        subprocess.run([ACTIVESURV, 'rig', 'nominal', '--out', str(rig)], check=True)
        data = yaml.safe_load(rig.read_text())
        data['obstacles'] = [POST]
        rig.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp / f'session{n}'
    subprocess.run(
        [ACTIVESURV, 'surveil', '--objects-at-once', str(n), '--duration', str(SESSION_S)]
        + ['--rig', str(rig), '--calibration', 'truth', '--out', str(out)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        timeout=SESSION_S * 3 + 600,
    )
    doc: dict[str, Any] = json.loads((out / 'results.json').read_text())
    return doc, out


def _figures(doc: dict[str, Any], run: Path) -> dict[str, Any]:
    rows = doc['demands']
    s = doc['summary']
    versus = compare(run)
    return {
        'cameras_vs_clairvoyant': _round(versus.get('cameras_ratio')),
        'visibility_vs_clairvoyant': _round(versus.get('visibility_ratio')),
        'greedy_visibility_vs_clairvoyant': _round(versus.get('greedy_visibility_ratio')),
        'clairvoyant_cameras_per_demand': _round(versus.get('clairvoyant_cameras_per_demand')),
        'greedy_cameras_seeing_per_demand': _round(versus.get('greedy_cameras_seeing_per_demand')),
        'demands': len(rows),
        'ok_fraction': round(sum(r['status'] == 'ok' for r in rows) / max(len(rows), 1), 4),
        'cameras_per_demand': round(float(np.mean([len(r['assigned']) for r in rows])), 3)
        if rows
        else None,
        'not_occluded_fraction': round(
            sum(not r.get('occluded') for r in rows) / max(len(rows), 1), 4
        ),
        'id_switches': s.get('id_switches'),
        'gospa_mean_mm': None if s.get('gospa_mean') is None else 1e3 * s['gospa_mean'],
        'max_objects_at_once': s.get('max_objects_at_once'),
        'latency_median_ms': s.get('latency_median_ms'),
    }


def _tracker_ms(n: int, frames: int = 100) -> tuple[float, float]:
    tracker = MultiTracker(interval=2.0, at_once=n)
    geometry = TargetGeometry.create((0.0, -0.03, -0.03), (0.0, -1.0, 0.0))
    ys = np.linspace(0.03, 0.17, n)
    rng = np.random.default_rng(0)
    times, horizon = [], []
    for k in range(frames):
        t = k / 10.0
        fixes = [
            np.array([0.05 + 0.02 * t if i % 2 else 0.45 - 0.02 * t, y]) + rng.normal(0, 3e-4, 2)
            for i, y in enumerate(ys)
        ]
        started = time.perf_counter()
        tracker.update(t, fixes)
        tracked = time.perf_counter()
        tracker.horizon(t, 5, geometry, 0.08)
        times.append(tracked - started)
        horizon.append(time.perf_counter() - tracked)
    return (
        round(1e3 * statistics.median(times[20:]), 3),
        round(1e3 * statistics.median(horizon[20:]), 3),
    )


def scaling() -> dict[str, Any]:
    """Cameras per demand as objects grow, 4 or 8 cameras (``scaling_<N>obj_<n>cam_*``)."""
    out: dict[str, Any] = {}
    for objects in (1, 2, 3, 4):
        for cameras in (4, 8):
            r = run_scaling(objects, cameras, seconds=SCALING_S)
            for key in ('cameras_per_demand', 'none_fraction', 'demands'):
                out[f'scaling_{objects}obj_{cameras}cam_{key}'] = r[key]
    return out


def run() -> dict[str, Any]:
    out: dict[str, Any] = {'session_s': SESSION_S, **scaling()}
    for n in (1, 3, 10):
        out[f'tracker_ms_per_frame_{n}'], out[f'horizon_ms_per_frame_{n}'] = _tracker_ms(n)
    with tempfile.TemporaryDirectory(prefix='activesurv-multi-') as tmp:
        for n, label in ((2, 'two'), (3, 'three')):
            figures = _figures(*_session(Path(tmp), n))
            print(f'  {n} objects at once: {figures}', flush=True)
            for key, value in figures.items():
                out[f'{label}_{key}'] = value
    return out
