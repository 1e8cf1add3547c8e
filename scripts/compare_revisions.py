"""Two revisions of activesurv on this host, in alternating runs: CPU and latency as ratios.

    .venv/bin/python scripts/compare_revisions.py --old /tmp/old --pairs 5 --out /tmp/cmp

Machines differ 2-4x in speed, so a figure such as ``realtime.cpu_cores`` measured on another
host (or in another hour of a shared one) says little about a change. This runs the same
experiment with two checkouts, each with its own ``.venv`` (``make setup`` in it), one after
the other and in alternating order, so that both see the same host in the same hour, and
reports the new revision's median CPU (cores over each run, the ``cpu.json`` of the run
directory) and median demand latency (``results.json``) as ratios of the old one's.

Each run gets a DDS domain of its own, localhost discovery and a ``ROS_HOME`` in a temporary
directory. Runs go to ``OUT/old_<i>`` and ``OUT/new_<i>``; ``OUT/summary.json`` holds every
run's figures and the ratios. ``OUT`` must not exist. Exits 1 if a run fails.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent.parent
EXPERIMENT = ['--set', 'A', '--system', 'fast', '--seed', '7']
_INHERITED = ('LD_LIBRARY_PATH', '_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'AMENT_PREFIX_PATH')


@dataclass(frozen=True)
class RunFigures:
    """One run's figures: its CPU over its own window and its demands' latencies (ms)."""

    revision: str
    cores: float
    latencies_ms: list[float]
    wall_seconds: float

    @property
    def latency_ms(self) -> float | None:
        return statistics.median(self.latencies_ms) if self.latencies_ms else None


def read_run(revision: str, run_dir: Path, wall_seconds: float) -> RunFigures:
    """The figures of a finished run directory (``cpu.json``, ``results.json``).

    Raises:
        ValueError: if either file is missing or holds no usable figure.
    """
    try:
        cpu = json.loads((run_dir / 'cpu.json').read_text())
        results = json.loads((run_dir / 'results.json').read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f'{run_dir}: no usable cpu.json / results.json ({exc})') from exc
    cores = cpu.get('cores')
    if not isinstance(cores, (int, float)):
        raise ValueError(f'{run_dir}/cpu.json has no "cores"')
    latencies = [
        1e3 * float(d['latency'])
        for d in results.get('demands', [])
        if isinstance(d.get('latency'), (int, float))
    ]
    return RunFigures(revision, float(cores), latencies, wall_seconds)


def summarise(runs: list[RunFigures]) -> dict[str, Any]:
    """Medians per revision and the new one's as ratios of the old one's."""
    out: dict[str, Any] = {}
    for rev in ('old', 'new'):
        mine = [r for r in runs if r.revision == rev]
        lat = [x for r in mine for x in r.latencies_ms]
        out[rev] = {
            'runs': len(mine),
            'cores_median': round(statistics.median(r.cores for r in mine), 3) if mine else None,
            'latency_ms_median': round(statistics.median(lat), 2) if lat else None,
            'latency_ms_p90': round(statistics.quantiles(lat, n=10)[-1], 2)
            if len(lat) >= 2
            else None,
        }
    for key in ('cores_median', 'latency_ms_median', 'latency_ms_p90'):
        old, new = out['old'][key], out['new'][key]
        out[f'{key}_new_to_old'] = round(new / old, 3) if old and new is not None else None
    return out


def _checkout(path: Path) -> Path:
    exe = path / '.venv' / 'bin' / 'activesurv'
    if not exe.is_file():
        raise SystemExit(f'error: {exe} not found: run `make setup` in {path} first')
    return exe


def _run(exe: Path, out: Path, domain: int, extra: list[str]) -> float:
    # Each checkout's own Python sets its library path (ROS wheels' bootstrap): none of ours.
    env = {k: v for k, v in os.environ.items() if k not in _INHERITED}
    env.update(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_HOME=tempfile.mkdtemp(prefix='ros_home_'),
        PYTHONDONTWRITEBYTECODE='1',
    )
    t0 = time.monotonic()
    with (out.parent / f'{out.name}.log').open('w') as log:
        rc = subprocess.call(
            [str(exe), 'experiment', *EXPERIMENT, *extra, '--out', str(out)],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    if rc != 0:
        raise SystemExit(f'error: {out.name} exited {rc}: see {out.parent / (out.name + ".log")}')
    return time.monotonic() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument(
        '--old', type=Path, required=True, help='the old checkout (its .venv set up)'
    )
    parser.add_argument('--new', type=Path, default=HERE, help='the new checkout (default: this)')
    parser.add_argument('--pairs', type=int, default=5, help='alternating pairs of runs')
    parser.add_argument('--out', type=Path, required=True, help='output directory (new)')
    parser.add_argument('--new-args', default='', help='extra experiment arguments, new revision')
    parser.add_argument('--old-args', default='', help='extra experiment arguments, old revision')
    args = parser.parse_args(argv)
    if args.pairs < 1:
        parser.error('--pairs must be at least 1')
    if args.out.exists():
        parser.error(f'{args.out} exists: choose a new output directory')
    exes = {'old': _checkout(args.old), 'new': _checkout(args.new)}
    extra = {'old': args.old_args.split(), 'new': args.new_args.split()}
    args.out.mkdir(parents=True)
    runs: list[RunFigures] = []
    base = 150 + os.getpid() % 50
    for i in range(args.pairs):
        order = ('old', 'new') if i % 2 == 0 else ('new', 'old')
        for j, rev in enumerate(order):
            run_dir = args.out / f'{rev}_{i}'
            wall = _run(exes[rev], run_dir, base + (2 * i + j) % 50, extra[rev])
            fig = read_run(rev, run_dir, wall)
            runs.append(fig)
            print(
                f'pair {i + 1}/{args.pairs} {rev}: {fig.cores:.3f} cores, '
                f'latency {fig.latency_ms} ms, {wall:.0f} s',
                flush=True,
            )
    summary = summarise(runs)
    doc: dict[str, Any] = {'old': str(args.old), 'new': str(args.new), 'summary': summary}
    doc['runs'] = [asdict(r) for r in runs]
    (args.out / 'summary.json').write_text(json.dumps(doc, indent=2) + '\n')
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
