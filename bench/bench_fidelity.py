"""Graph-lockstep fidelity (``fidelity.*``): the node graph at rtf 1 against lockstep.

The six experiments (Sets A and B, static, medium and fast) over the seeds of
``ACTIVESURV_BENCH_FIDELITY_SEEDS`` (1,2,3 by default) on the default rig and its cached
calibration, once in lockstep (in this process) and once as the node graph at rtf 1
(``activesurv experiment``), then the same graph runs again with one core taken by a busy
process (``hog_*``):

* ``served_lost``: demands lockstep answers ``ok`` that the graph does not (goal 0);
* ``same_cameras_fraction``: demands given the same number of cameras in both modes (>= 0.98);
* ``same_status_fraction``: demands with the same status in both modes;
* ``all_dropped_runs``: graph runs in which the dispatcher dropped every camera (goal 0);
* ``stalls``: stalls the dispatcher recognised (every camera silent at once), summed;
* ``disagreements``: every demand that differs, with both modes' cameras and reasons;
* ``kept_runs``: where the graph runs that differed were copied (bag, logs, results), under
  ``activesurv-fidelity-kept`` in the temporary directory, to be looked at after the bench.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from activesurv_bringup.experiments.experiment import load_experiment
from activesurv_bringup.experiments.lockstep import run_lockstep
from activesurv_bringup.files import cache_dir
from activesurv_bringup.rig.choice import choose
from activesurv_bringup.rig.commission import run_commission

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
SEEDS = [int(s) for s in os.environ.get('ACTIVESURV_BENCH_FIDELITY_SEEDS', '1,2,3').split(',')]
CAMERAS = 4  # the paper's set-up
EXPERIMENTS = [(s, m) for s in 'AB' for m in ('static', 'medium', 'fast')]


def _busy() -> None:
    while True:
        pass


def _graph(set_name: str, system: str, seed: int, out: Path) -> dict[str, Any]:
    subprocess.run(
        [ACTIVESURV, 'experiment', '--set', set_name, '--system', system, '--seed', str(seed)]
        + ['--out', str(out)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        timeout=600,
    )
    doc: dict[str, Any] = json.loads((out / 'results.json').read_text())
    lines = (out / 'logs' / 'core.log').read_text(errors='replace').splitlines()
    down: set[str] = set()
    doc['_all_dropped'] = False
    for line in lines:
        if '[dispatcher]' not in line:
            continue
        text = line.split('[dispatcher]: ', 1)[-1]
        camera = text.split(':')[0].split(' ')[0]
        if 'dispatching without it' in text:
            down.add(camera)
        elif 'is back' in text:
            down.discard(camera)
        doc['_all_dropped'] |= len(down) >= CAMERAS
    doc['_stalls'] = sum('stalled; no camera is dropped' in line for line in lines)
    return doc


def _differs(lock: list[Any], graph: dict[str, Any]) -> bool:
    """Whether any demand of a run has another status or number of cameras than lockstep's."""
    return any(
        len(rl.assigned) != len(rg['assigned']) or rl.status != rg['status']
        for rl, rg in zip(lock, graph['demands'], strict=True)
    )


def _keep(run_dir: Path) -> str:
    """A copy of a run that differed (bag, logs, results) where it outlives the bench."""
    keep = Path(tempfile.gettempdir()) / 'activesurv-fidelity-kept'
    keep.mkdir(exist_ok=True)
    target = Path(tempfile.mkdtemp(prefix=f'{run_dir.name}-', dir=keep))
    shutil.copytree(run_dir, target, dirs_exist_ok=True)
    return str(target)


def _compare(runs: list[tuple[str, str, int, list[Any], dict[str, Any]]]) -> dict[str, Any]:
    total = same_n = same_status = lost = 0
    disagreements = []
    for set_name, system, seed, lock, graph in runs:
        for rl, rg in zip(lock, graph['demands'], strict=True):
            total += 1
            n_l, n_g = len(rl.assigned), len(rg['assigned'])
            same_n += n_l == n_g
            same_status += rl.status == rg['status']
            lost += rl.status == 'ok' and rg['status'] != 'ok'
            if n_l != n_g or rl.status != rg['status']:
                disagreements.append(
                    f'{set_name} {system} seed {seed} demand {rl.index}: lockstep {rl.status} '
                    f'{sorted(rl.assigned)}, graph {rg["status"]} {sorted(rg["assigned"])}'
                    + (f' ({rg["reason"]})' if rg.get('reason') else '')
                )
    return {
        'demands': total,
        'served_lost': lost,
        'same_cameras_fraction': round(same_n / max(total, 1), 4),
        'same_status_fraction': round(same_status / max(total, 1), 4),
        'all_dropped_runs': sum(bool(g.get('_all_dropped')) for *_, g in runs),
        'stalls': sum(int(g.get('_stalls', 0)) for *_, g in runs),
        'disagreements': disagreements,
    }


def _say(text: str) -> None:
    print(f'  {text}', flush=True)


def run() -> dict[str, Any]:
    choice = choose(None, None, 1, cache_dir(), _say, run_commission)
    lockstep = {
        (s, m, seed): run_lockstep(load_experiment(s, m, seed, rig=choice))
        for s, m in EXPERIMENTS
        for seed in SEEDS
    }
    out: dict[str, Any] = {'seeds': SEEDS}
    kept: list[str] = []
    with tempfile.TemporaryDirectory(prefix='activesurv-fidelity-') as tmp:
        for label in ('', 'hog_'):
            hog = None
            if label:
                hog = multiprocessing.Process(target=_busy, daemon=True)
                hog.start()
            try:
                runs = []
                for (s, m, seed), lock in lockstep.items():
                    run_dir = Path(tmp) / f'{label}{s}_{m}_{seed}'
                    doc = _graph(s, m, seed, run_dir)
                    runs.append((s, m, seed, lock, doc))
                    if _differs(lock, doc):  # kept to be looked at: its bag, logs and frames
                        kept.append(_keep(run_dir))
                    print(
                        f'  {label}{s} {m} seed {seed}: graph cameras '
                        + ''.join(str(len(d['assigned'])) for d in doc['demands'])
                        + ', lockstep '
                        + ''.join(str(len(r.assigned)) for r in lock),
                        flush=True,
                    )
            finally:
                if hog is not None:
                    hog.terminate()
            for key, value in _compare(runs).items():
                out[f'{label}{key}'] = value
    out['kept_runs'] = kept
    return out
