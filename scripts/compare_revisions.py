"""Two revisions of activesurv on this host, in alternating runs: CPU and latency as ratios.

    .venv/bin/python scripts/compare_revisions.py --old /tmp/old --pairs 5 --out /tmp/cmp

Machines differ 2-4x in speed, so a figure such as ``realtime.cpu_cores`` measured on another
host (or in another hour of a shared one) says little about a change. This runs the same
experiment with two checkouts, each with its own ``.venv`` (``make setup`` in it), one after
the other and in alternating order, so that both see the same host in the same hour, and
reports the new revision's median CPU and demand latency (``results.json``) as ratios of the
old one's. The CPU three ways: ``cores`` and ``cpu_seconds`` of the run's ``cpu.json`` (every
process over the run's own window, which each revision may draw differently: one that starts
simulated time later counts its start in it), and ``running_cores``, measured here alike for
both, the run's process tree from the progress line of the first demand answered to that of
the last (``/proc``).

Each run gets a DDS domain of its own, localhost discovery and a ``ROS_HOME`` in a temporary
directory. Runs go to ``OUT/old_<i>`` and ``OUT/new_<i>``; ``OUT/summary.json`` holds every
run's figures and the ratios. ``OUT`` must not exist. Exits 1 if a run fails.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
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
    cpu_seconds: float = math.nan  # every process's CPU over the run's own window
    running_cores: float | None = None  # the process tree from the first to the last demand

    @property
    def latency_ms(self) -> float | None:
        return statistics.median(self.latencies_ms) if self.latencies_ms else None


def read_run(
    revision: str, run_dir: Path, wall_seconds: float, running_cores: float | None = None
) -> RunFigures:
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
    used = cpu.get('cpu_seconds')
    spent = sum(used.values()) if isinstance(used, dict) else math.nan
    return RunFigures(revision, float(cores), latencies, wall_seconds, spent, running_cores)


def _median(values: list[float | None], digits: int) -> float | None:
    known = [v for v in values if v is not None and math.isfinite(v)]
    return round(statistics.median(known), digits) if known else None


def summarise(runs: list[RunFigures]) -> dict[str, Any]:
    """Medians per revision and the new one's as ratios of the old one's."""
    out: dict[str, Any] = {}
    for rev in ('old', 'new'):
        mine = [r for r in runs if r.revision == rev]
        lat = [x for r in mine for x in r.latencies_ms]
        out[rev] = {
            'runs': len(mine),
            'cores_median': _median([r.cores for r in mine], 3),
            'cpu_seconds_median': _median([r.cpu_seconds for r in mine], 2),
            'running_cores_median': _median([r.running_cores for r in mine], 3),
            'latency_ms_median': round(statistics.median(lat), 2) if lat else None,
            'latency_ms_p90': round(statistics.quantiles(lat, n=10)[-1], 2)
            if len(lat) >= 2
            else None,
        }
    keys = ('cores_median', 'cpu_seconds_median', 'running_cores_median', 'latency_ms_median')
    for key in (*keys, 'latency_ms_p90'):
        old, new = out['old'][key], out['new'][key]
        out[f'{key}_new_to_old'] = round(new / old, 3) if old and new is not None else None
    return out


def _checkout(path: Path) -> Path:
    exe = path / '.venv' / 'bin' / 'activesurv'
    if not exe.is_file():
        raise SystemExit(f'error: {exe} not found: run `make setup` in {path} first')
    return exe


def tree_cpu_seconds(root: int, proc: Path = Path('/proc')) -> float:
    """CPU seconds (user + system) of process ``root`` and every live descendant."""
    parent: dict[int, int] = {}
    ticks: dict[int, int] = {}
    for stat in proc.glob('[0-9]*/stat'):
        try:
            text = stat.read_text()
        except OSError:
            continue  # the process ended meanwhile
        fields = text[text.rindex(')') + 2 :].split()  # after "pid (comm) "
        pid = int(stat.parent.name)
        parent[pid] = int(fields[1])
        ticks[pid] = int(fields[11]) + int(fields[12])  # utime, stime
    tree, todo = set(), [root]
    while todo:
        pid = todo.pop()
        if pid in ticks and pid not in tree:
            tree.add(pid)
            todo += [c for c, p in parent.items() if p == pid]
    return sum(ticks[p] for p in tree) / os.sysconf('SC_CLK_TCK')


_ANSWERED = re.compile(r'demand (\d+) of (\d+)')


def _run(exe: Path, out: Path, domain: int, extra: list[str]) -> tuple[float, float | None]:
    """Run one experiment; its wall seconds and the cores its process tree used from the
    first demand answered (1 of N) to the last (N of N), read off its progress lines."""
    # Each checkout's own Python sets its library path (ROS wheels' bootstrap): none of ours.
    env = {k: v for k, v in os.environ.items() if k not in _INHERITED}
    env.update(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_HOME=tempfile.mkdtemp(prefix='ros_home_'),
        PYTHONDONTWRITEBYTECODE='1',
    )
    t0 = time.monotonic()
    marks: list[tuple[float, float]] = []
    log_path = out.parent / f'{out.name}.log'
    with log_path.open('w') as log:
        child = subprocess.Popen(
            [str(exe), 'experiment', *EXPERIMENT, *extra, '--out', str(out)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        assert child.stdout is not None
        for line in child.stdout:
            log.write(line)
            m = _ANSWERED.search(line)
            if m and m.group(1) in ('1', m.group(2)):
                marks.append((time.monotonic(), tree_cpu_seconds(child.pid)))
        rc = child.wait()
    if rc != 0:
        raise SystemExit(f'error: {out.name} exited {rc}: see {log_path}')
    running = None
    if len(marks) >= 2 and marks[-1][0] > marks[0][0]:
        running = (marks[-1][1] - marks[0][1]) / (marks[-1][0] - marks[0][0])
    return time.monotonic() - t0, running


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
            wall, running = _run(exes[rev], run_dir, base + (2 * i + j) % 50, extra[rev])
            fig = read_run(rev, run_dir, wall, running)
            runs.append(fig)
            print(
                f'pair {i + 1}/{args.pairs} {rev}: {fig.cores:.3f} cores '
                f'({fig.cpu_seconds:.2f} CPU s; {fig.running_cores} cores running), '
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
