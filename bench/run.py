"""Run the benchmarks and write ``bench/results.json``.

Every ``bench/bench_*.py`` module has ``run() -> dict[str, object]``; its keys are prefixed with
the module's area (``fusion.``, ``imaging.``, ...). Timings are medians over many repetitions,
and comparisons are ratios, so that a noisy shared machine moves them little.
Usage: ``python bench/run.py [--out bench/results.json] [--only fusion,imaging]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--out', type=Path, default=HERE / 'results.json')
    parser.add_argument('--only', default='', help='comma-separated areas to run')
    args = parser.parse_args(argv)
    # Benchmarks that start node graphs keep to this machine and a domain of their own.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 100))
    only = {a for a in args.only.split(',') if a}
    results: dict[str, Any] = {}
    if args.out.exists():
        results = json.loads(args.out.read_text())  # keep areas that are not re-run
    for path in sorted(HERE.glob('bench_*.py')):
        area = path.stem.removeprefix('bench_')
        if only and area not in only:
            continue
        spec = importlib.util.spec_from_file_location(path.stem, path)
        if spec is None or spec.loader is None:
            raise ImportError(f'cannot load benchmark module {path}')
        module = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = module  # worker processes find its functions by name
        spec.loader.exec_module(module)
        print(f'bench: {area} ...', flush=True)
        t0 = time.perf_counter()
        fresh = module.run()
        for stale in [k for k in results if k.startswith(f'{area}.')]:
            del results[stale]  # a key this version no longer writes must not linger
        for key, value in fresh.items():
            results[f'{area}.{key}'] = value
        print(f'bench: {area} done in {time.perf_counter() - t0:.1f} s', flush=True)
    results['_machine'] = {
        'python': sys.version.split()[0],
        'platform': platform.platform(),
        'when': time.strftime('%Y-%m-%dT%H:%M:%S'),
    }
    args.out.write_text(json.dumps(dict(sorted(results.items())), indent=2) + '\n')
    for key, value in sorted(results.items()):
        if not key.startswith('_') and not isinstance(value, (dict, list)):
            print(f'  {key:45s} {value}')
    print(f'wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
