"""Set C, our named set beside the paper's A and B: two objects at once crossing in opposite
directions and a post in the cell, run as a short node-graph session at rtf 1
(``experiment --set C``): the results contract of a session with the set's name, every demand
of one of the two objects, no assigned camera blocked, the tracks kept apart, and the report
with the scene from above."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.graph, pytest.mark.slow]
ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def test_set_c_two_objects_and_a_post(tmp_path: Path) -> None:
    out = tmp_path / 'C_fast'
    r = subprocess.run(
        [ACTIVESURV, 'experiment', '--set', 'C', '--system', 'fast', '--calibration', 'truth',
         '--out', str(out)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    doc = json.loads((out / 'results.json').read_text())
    assert doc['mode'] == 'surveil'
    assert doc['set'] == 'C'
    assert len(doc['obstacles']) == 1
    assert [o['truth_id'] for o in doc['objects']] == [1, 2]
    demands = doc['demands']
    assert {d['object'] for d in demands} == {o['id'] for o in doc['objects']}
    assert len(demands) >= 10
    assert all(d['occluded'] == [] for d in demands)  # never a blocked camera assigned
    ok = [d for d in demands if d['status'] == 'ok']
    assert len(ok) >= 0.8 * len(demands), [(d['index'], d['status'], d['reason']) for d in demands]
    assert max(d['position_error'] for d in ok) < 1e-3
    s = doc['summary']
    assert s['max_objects_at_once'] == 2
    assert s['id_switches'] == 0
    assert 0.0 < s['gospa_mean'] < 0.02
    report = (out / 'report.md').read_text()
    assert report.startswith('# activesurv Set C')
    assert (out / 'scene_top.png').stat().st_size > 10_000
    assert 'Set C' in r.stdout or 'two objects' in r.stdout
