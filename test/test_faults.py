"""Reliability: faulty cameras are discarded by Optimal Region and reported (issue 8, point 1).

Lockstep runs (deterministic, the same cores as the graph) inject each fault kind into one camera
of the fast system; a graph run checks that ``--fault`` reaches the real nodes too.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.experiments.experiment import load_experiment
from activesurv_bringup.experiments.faults import parse_fault
from activesurv_bringup.experiments.lockstep import run_lockstep
from activesurv_evaluation.results import results_document

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def _run(fault: str, seed: int = 4) -> dict:  # type: ignore[type-arg]
    exp = load_experiment('A', 'fast', seed)
    return results_document('A', 'fast', run_lockstep(exp, [parse_fault(fault)]))


def _used(doc: dict, cam: str) -> list[dict]:  # type: ignore[type-arg]
    """Demands where ``cam`` was assigned and answered."""
    return [d for d in doc['demands'] if cam in d['assigned'] and d['status'] != 'not_captured']


@pytest.mark.cross
@pytest.mark.parametrize('fault', ['cam1:bias:0.003', 'cam1:noise:0.003', 'cam1:flip'])
def test_a_faulty_camera_is_discarded_and_reported(fault: str) -> None:
    doc = _run(fault)
    used = _used(doc, 'cam1')
    assert len(used) >= 5
    flagged = [d for d in used if 'cam1' in d['faulty']]
    assert len(flagged) >= 0.8 * len(used), [(d['index'], d['faulty']) for d in used]
    # The estimate stays accurate: the faulty reading did not drag it.
    for d in flagged:
        assert d['position_error'] < 0.5e-3
        assert 'cam1' not in d['cameras']


@pytest.mark.cross
def test_a_frozen_camera_is_caught() -> None:
    doc = _run('cam4:frozen')
    used = [d for d in _used(doc, 'cam4') if d['index'] > 0]  # its first frame is still true
    flagged = [d for d in used if 'cam4' in d['faulty'] or 'cam4' not in d['cameras']]
    assert len(flagged) >= 0.8 * len(used)
    assert all(d['position_error'] is None or d['position_error'] < 0.5e-3 for d in doc['demands'])


@pytest.mark.cross
def test_a_dead_camera_is_never_assigned() -> None:
    doc = _run('cam1:dead')
    assert all('cam1' not in d['assigned'] for d in doc['demands'])
    assert sum(d['estimated_position'] is not None for d in doc['demands']) == 10


@pytest.mark.cross
def test_fault_syntax_errors_are_clear() -> None:
    with pytest.raises(ConfigError, match='unknown kind'):
        parse_fault('cam1:melt:1')
    with pytest.raises(ConfigError, match='needs a magnitude'):
        parse_fault('cam1:bias')
    with pytest.raises(ConfigError, match='not a number'):
        parse_fault('cam1:noise:lots')


@pytest.mark.graph
@pytest.mark.slow
def test_graph_mode_reports_the_faulty_camera(tmp_path: Path) -> None:
    r = subprocess.run(
        [
            ACTIVESURV,
            'experiment',
            '--set',
            'A',
            '--system',
            'fast',
            '--out',
            str(tmp_path / 'run'),
            '--seed',
            '4',
            '--fault',
            'cam1:bias:0.003',
        ],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    doc = json.loads((tmp_path / 'run' / 'results.json').read_text())
    assert doc['faults'] == ['cam1:bias:0.003']
    used = _used(doc, 'cam1')
    assert sum('cam1' in d['faulty'] for d in used) >= 0.8 * len(used)
    assert all(d['position_error'] is None or d['position_error'] < 0.5e-3 for d in doc['demands'])
