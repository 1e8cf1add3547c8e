"""Hardware mode on the hardware-in-the-loop lab (``hardware.*``), at real time.

``activesurv lab`` on the nominal rig (its cameras free-running at 30 Hz, best effort, 20 ms
delay, 2 ms jitter, 1 % drops; controllers on pseudo-terminals), the system told the nominal
calibration (so errors are the method's, not a calibration's):

* ``setA_fast_ok`` / ``setA_fast_k``: Set A fast demands answered ``ok``, and those with k = 3
  cameras used; ``median_error_mm``: median position error against the table controller's
  reports; ``frame_offset_abs_median_ms`` / ``_max_ms``: |frame stamp - demand instant|;
* ``median_error_mm_uncorrected``: the same run with ``--no-motion-correction``;
* ``external_table_ok`` / ``external_table_error_mm``: the experiment with the table on an
  external GRBL controller (an emulator started here, handed over with ``--controller
  table=PORT``);
* ``surveil_ok_fraction``, ``surveil_latency_median_ms``, ``surveil_latency_p90_ms``,
  ``surveil_demands``: ``surveil --hardware`` for ``ACTIVESURV_BENCH_SURVEIL_S`` seconds (600 by
  default: the issue's 10 minutes), ``surveil_estimated_fraction`` the demands with an estimate
  (``ok``, or ``partial``: fused from fewer cameras than assigned); ``surveil_not_ok`` and
  ``setA_fast_not_ok`` list the demands short of ok (or of k cameras) with their reasons.
* ``latency_bound_ms``: what a free-running camera allows (issue 35): its own delay plus the
  median wait for the first frame after the instant (half a frame period) plus the compute on
  the critical path (the session's median of its slowest camera's imaging CPU plus fusion's,
  per demand);
  ``surveil_latency_to_bound`` = the session's median latency over it. The camera's delay is
  measured (``camera_delay_ms``: the median of every frame's arrival at its imager after its
  exposure, :func:`activesurv_evaluation.timing.camera_delays`): the lab's cameras declare
  20 ms of exposure and read-out, but wait for the controllers' reports of where the stages
  and the table were at the exposure and then render, so they deliver later than a real
  camera would. ``latency_bound_nominal_ms`` / ``surveil_latency_to_nominal_bound``: the same
  with the declared 20 ms.
"""

from __future__ import annotations

import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_bringup.rig.lab import EXPOSURE_DELAY, table_controller
from activesurv_bringup.rig.rigs import nominal
from activesurv_evaluation.timing import camera_delays, critical_compute, frames_bound
from activesurv_sim.rig import save_rig

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
SURVEIL_S = float(os.environ.get('ACTIVESURV_BENCH_SURVEIL_S', '600'))
# The lab cameras' frame rate (Hz); and 1 to measure the session alone (diagnosis).
LAB_RATE = float(os.environ.get('ACTIVESURV_BENCH_LAB_RATE', '30'))
SURVEIL_ONLY = os.environ.get('ACTIVESURV_BENCH_SURVEIL_ONLY', '') == '1'


def _lab(rig: Path, out: Path, *extra: str) -> subprocess.Popen[str]:
    log = out.with_name(f'{out.name}.log')  # (a pipe nobody reads would fill and stall it)
    with log.open('w') as f:
        lab = subprocess.Popen(
            [ACTIVESURV, 'lab', '--rig', str(rig), '--out', str(out), '--frame-rate',
             str(LAB_RATE), *extra],
            stdout=f, stderr=subprocess.STDOUT, text=True,
        )  # fmt: skip
    deadline = time.monotonic() + 60.0
    while not (out / 'hardware.yaml').exists():
        if lab.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f'the lab did not come up: {log.read_text()[-2000:]}')
        time.sleep(0.2)
    time.sleep(3.0)
    return lab


def _stop(lab: subprocess.Popen[str]) -> None:
    lab.send_signal(signal.SIGINT)
    lab.wait(timeout=60)


def _experiment(hw: Path, out: Path, *extra: str) -> dict[str, Any]:
    r = subprocess.run(
        [ACTIVESURV, 'experiment', '--hardware', str(hw), '--yes', '--calibration', 'nominal',
         '--home', '--set', 'A', '--system', 'fast', '--out', str(out), *extra],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    if r.returncode != 0:
        raise RuntimeError(r.stdout[-2000:] + r.stderr[-2000:])
    return dict(json.loads((out / 'results.json').read_text()))


def _figures(doc: dict[str, Any]) -> dict[str, Any]:
    rows = doc['demands']
    errors = [r['position_error'] for r in rows if r.get('position_error') is not None]
    offsets = [abs(v) for r in rows for v in r['frame_offsets'].values()]
    return {
        'ok': sum(r['status'] == 'ok' for r in rows),
        'k': sum(len(r['cameras']) == 3 for r in rows),
        'error_mm': round(1e3 * float(np.median(errors)), 4) if errors else None,
        'offset_median_ms': round(1e3 * float(np.median(offsets)), 2) if offsets else None,
        'offset_max_ms': round(1e3 * max(offsets), 2) if offsets else None,
        'not_ok': [
            f'{r["index"]} {r["status"]}: {str(r.get("reason") or "")[:160]}'
            for r in rows
            if r['status'] != 'ok' or len(r['cameras']) < 3
        ],
    }


def run() -> dict[str, Any]:
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix='bench_hardware_') as tmp:
        d = Path(tmp)
        rig = d / 'rig.yaml'
        save_rig(nominal(), rig)
        lab = _lab(rig, d / 'lab')
        hw = d / 'lab' / 'hardware.yaml'
        try:
            if not SURVEIL_ONLY:
                corrected = _figures(_experiment(hw, d / 'A_fast'))
                raw = _figures(_experiment(hw, d / 'A_fast_raw', '--no-motion-correction'))
            started = time.monotonic()
            r = subprocess.run(
                [ACTIVESURV, 'surveil', '--hardware', str(hw), '--yes', '--calibration', 'nominal',
                 '--out', str(d / 'session'), '--duration', str(SURVEIL_S), '--home'],
                capture_output=True, text=True, timeout=SURVEIL_S * 2 + 300,
            )  # fmt: skip
            wall = time.monotonic() - started
        finally:
            _stop(lab)
        if r.returncode != 0:
            raise RuntimeError(r.stdout[-2000:] + r.stderr[-2000:])
        session = json.loads((d / 'session' / 'results.json').read_text())
        lat = [x['latency'] for x in session['demands'] if x.get('latency') is not None]
        spent = [c for x in session['demands'] if (c := critical_compute(x.get('timing') or {}))]
        rest = 0.5 / LAB_RATE + (statistics.median(spent) if spent else 0.0)
        delays = camera_delays(session['demands'])
        delay = statistics.median(delays) if delays else EXPOSURE_DELAY
        bound, declared = delay + rest, EXPOSURE_DELAY + rest
        # Each demand against its own frames: the slowest of its cameras' arrivals + compute.
        own = [
            (x['latency'], b)
            for x in session['demands']
            if x.get('latency') is not None and (b := frames_bound(x)) is not None
        ]
        out.update(
            camera_delay_ms=round(1e3 * delay, 1),
            latency_bound_ms=round(1e3 * bound, 1),
            surveil_latency_to_bound=round(statistics.median(lat) / bound, 2) if lat else None,
            latency_bound_nominal_ms=round(1e3 * declared, 1),
            camera_delay_p90_ms=round(1e3 * float(np.percentile(delays, 90)), 1)
            if delays
            else None,
            frames_bound_ms=(
                round(1e3 * statistics.median(b for _, b in own), 1) if own else None
            ),
            surveil_latency_to_frames_bound=(
                round(statistics.median(lat_j / b for lat_j, b in own), 2) if own else None
            ),
            surveil_latency_to_nominal_bound=(
                round(statistics.median(lat) / declared, 2) if lat else None
            ),
            camera_rate_hz=LAB_RATE,
            surveil_seconds=SURVEIL_S,
            surveil_wall_seconds=round(wall, 1),
            surveil_demands=session['summary']['demands'],
            surveil_ok_fraction=round(
                session['summary']['ok'] / max(session['summary']['demands'], 1), 4
            ),
            # an estimate, from every assigned camera (ok) or from fewer (partial)
            surveil_estimated_fraction=round(
                sum(x['estimated_position'] is not None for x in session['demands'])
                / max(session['summary']['demands'], 1),
                4,
            ),
            surveil_latency_median_ms=round(1e3 * statistics.median(lat), 1) if lat else None,
            surveil_latency_p90_ms=round(1e3 * float(np.percentile(lat, 90)), 1) if lat else None,
            # what the shortfall is made of: each demand not ok, with its reason
            surveil_not_ok=[
                f'{x["index"]} {x["status"]}: {str(x.get("reason") or "")[:160]}'
                for x in session['demands']
                if x['status'] != 'ok'
            ],
        )
        if SURVEIL_ONLY:
            return out
        # The table on an external controller: an emulator that is not the lab's, on its port.
        emu, _ = table_controller(d / 'ttyEXTERNAL')
        try:
            lab = _lab(rig, d / 'lab2', '--controller', f'table={d / "ttyEXTERNAL"}')
            try:
                external = _figures(_experiment(d / 'lab2' / 'hardware.yaml', d / 'ext'))
            finally:
                _stop(lab)
        finally:
            emu.close()
    out.update(
        setA_fast_ok=f'{corrected["ok"]}/10',
        setA_fast_k=f'{corrected["k"]}/10',
        median_error_mm=corrected['error_mm'],
        median_error_mm_uncorrected=raw['error_mm'],
        frame_offset_abs_median_ms=corrected['offset_median_ms'],
        frame_offset_abs_max_ms=corrected['offset_max_ms'],
        external_table_ok=f'{external["ok"]}/10',
        external_table_error_mm=external['error_mm'],
        setA_fast_not_ok=corrected['not_ok'],
    )
    return out
