"""Soak: a continuous session at rtf 1 (issue: real time and continuous operation).

``activesurv surveil --duration 1800 --rtf 1`` (``ACTIVESURV_SOAK_SECONDS`` to change the
length), Set A fast cameras, objects every 30 s, a demand every 2 s, bag split every 300 s.

* ``ok_fraction``: demands answered ``ok`` over all demands with a capture request.
* ``rss_growth_mb_max``: the largest growth of any process's resident memory between minute 5
  and the end (``rss_growth_mb`` itemises it).
* ``latency_ms_first5`` / ``latency_ms_last5``: median latency of the demands of the first and
  the last 5 minutes; ``latency_drift``: their ratio minus 1.
"""

from __future__ import annotations

import json
import os
import statistics
import tempfile
from pathlib import Path

SECONDS = float(os.environ.get('ACTIVESURV_SOAK_SECONDS', '1800'))


def summarise(run_dir: Path, seconds: float) -> dict[str, object]:
    """The soak figures of a finished session directory (results.json, resources.json)."""
    doc = json.loads((run_dir / 'results.json').read_text())
    res = json.loads((run_dir / 'resources.json').read_text())['samples']
    demands = doc['demands']
    ok = [d for d in demands if d['status'] == 'ok']
    window = min(300.0, seconds / 3)
    first = [d['latency'] for d in demands if d['t'] < window and d.get('latency') is not None]
    last = [
        d['latency']
        for d in demands
        if d['t'] >= seconds - window and d.get('latency') is not None
    ]
    start = next((s for s in res if s['wall'] >= min(300.0, seconds / 6)), res[0])
    end = res[-1]
    growth = {
        k: round(end['rss_mb'][k] - start['rss_mb'][k], 2)
        for k in end['rss_mb']
        if k in start['rss_mb']
    }
    l1 = statistics.median(first) if first else None
    l2 = statistics.median(last) if last else None
    out: dict[str, object] = {
        'seconds': seconds,
        'objects': len(doc['objects']),
        'demands': len(demands),
        'ok_fraction': round(len(ok) / len(demands), 4) if demands else None,
        'rss_growth_mb': growth,
        'rss_growth_mb_max': max(growth.values()) if growth else None,
        'rss_mb_end': end['rss_mb'],
        'latency_ms_first5': None if l1 is None else round(1e3 * l1, 1),
        'latency_ms_last5': None if l2 is None else round(1e3 * l2, 1),
        'latency_drift': None if not (l1 and l2) else round(l2 / l1 - 1.0, 3),
        'failed': [
            {
                'index': d['index'],
                'object': d['object'],
                'status': d['status'],
                'reason': d['reason'],
            }
            for d in demands
            if d['status'] != 'ok'
        ][:20],
    }
    return out


def run() -> dict[str, object]:
    from activesurv_bringup.experiments.options import RunOptions
    from activesurv_bringup.experiments.session_options import SurveilOptions
    from activesurv_bringup.experiments.surveil import run_surveil

    out: dict[str, object] = {'load_average_1min': round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory() as name:
        run_dir = Path(name) / 'soak'
        run_dir.mkdir()
        s = SurveilOptions(duration=SECONDS, max_bag_duration=300.0, seed=11)
        run_surveil(
            run_dir, s, RunOptions(rtf=1.0), progress=lambda line: print('  ' + line, flush=True)
        )
        out.update(summarise(run_dir, SECONDS))
    return out
