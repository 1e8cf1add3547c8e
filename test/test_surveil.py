"""Continuous surveillance, the short version of the soak (about a minute): two objects at
once at rtf 1 (lanes, every marker tracked, staggered demands), a split bag, a clean stop on
SIGINT that answers every open demand, and the results contract (``objects``, ``demands`` with
``object`` and ``occluded``, ``summary`` with the tracking figures)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from activesurv_studies.clairvoyant import compare

pytestmark = [pytest.mark.graph, pytest.mark.slow]
ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
EXPERIMENT_KEYS = {'index', 't', 'true_position', 'estimated_position', 'visibility', 'cameras'}


def test_surveil_runs_two_objects_at_once_and_stops_cleanly_on_sigint(
    tmp_path: Path,
) -> None:
    out = tmp_path / 'session'
    proc = subprocess.Popen(
        [
            ACTIVESURV,
            'surveil',
            '--out',
            str(out),
            '--arrival-interval',
            '26',
            '--demand-interval',
            '2',
            '--max-bag-duration',
            '10',
            '--seed',
            '11',  # a parabola (1-26 s) and an arc (14-39 s)
            '--objects-at-once',
            '2',
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []
    assert proc.stdout is not None
    deadline = time.monotonic() + 240.0
    try:
        for line in proc.stdout:
            lines.append(line)
            # Stop once the first has left and the second is being surveyed (time >= 30 s).
            m = re.search(r'simulated time (\d+) s', line)
            if (m and int(m.group(1)) >= 30) or time.monotonic() > deadline:
                break
        os.kill(proc.pid, signal.SIGINT)
        rest, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    text = ''.join(lines) + rest
    assert proc.returncode == 0, text[-3000:]
    assert 'SIGINT at simulated time' in text

    doc = json.loads((out / 'results.json').read_text())
    assert doc['mode'] == 'surveil'
    assert len(doc['objects']) >= 2
    for o in doc['objects']:
        assert {'id', 'entered', 'left', 'path_kind'} <= set(o)
    assert doc['objects'][0]['left'] is not None
    demands = doc['demands']
    assert len(demands) >= 8
    for d in demands:
        assert set(d) >= EXPERIMENT_KEYS
        assert d['object'] in {o['id'] for o in doc['objects']}
        assert d['status'] != 'no_answer', d  # nothing requested was left unanswered
    assert all(d['occluded'] == [] for d in demands)  # nothing stood in the way
    # Two at once, each followed by one track all along (ids from the truth's lanes).
    summary = doc['summary']
    assert summary['max_objects_at_once'] == 2
    assert summary['id_switches'] == 0
    assert 0.0 < summary['gospa_mean'] < 0.02
    assert len({d['object'] for d in demands}) >= 2
    # Against a clairvoyant dispatcher (true positions and occlusions) from the same poses.
    versus = compare(out)
    assert versus['demands'] == len([d for d in demands if d.get('true_position')])
    assert versus['cameras_ratio'] > 0.8, {k: v for k, v in versus.items() if k != 'rows'}
    ok = [d for d in demands if d['status'] == 'ok']
    assert len(ok) >= 0.8 * len(demands), [(d['index'], d['status'], d['reason']) for d in demands]
    # A demand answered after the stop ended the table has no truth (no error), not a stale one.
    errors = [d['position_error'] for d in ok if d['true_position'] is not None]
    assert errors
    assert max(errors) < 1e-3
    assert all(d['position_error'] is None for d in ok if d['true_position'] is None)

    meta = yaml.safe_load((out / 'bag' / 'metadata.yaml').read_text())
    files = meta['rosbag2_bagfile_information']['relative_file_paths']
    assert len(files) >= 3
    assert files == [f'bag_{k}.mcap' for k in range(len(files))]
    assert all((out / 'bag' / f).is_file() for f in files)

    # The same results from the bag alone (report reads split bags).
    r = subprocess.run(
        [ACTIVESURV, 'report', str(out)], capture_output=True, text=True, timeout=120, check=False
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
