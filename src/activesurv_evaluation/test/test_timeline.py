"""The call traces of a run's processes placed around its demand instants."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from activesurv_evaluation.timeline import (
    ESTIMATE,
    OBSERVATION,
    demand_windows,
    load_traces,
    occupancy,
    summarise,
    write_timeline,
)

T0 = 1_700_000_000.0  # the wall clock of the first demand's instant


def _run(tmp_path: Path, rtf: float = 1.0) -> Path:
    """Two demands 1 s apart: two cameras each image 6 ms of CPU in 10 ms of wall time and
    publish an observation; fusion answers 1 ms after the later one (12 and 11 ms after the
    instants, in simulated seconds); demand 1 has no estimate."""
    calls: dict[str, list[list[object]]] = {'cam1': [], 'cam2': [], 'fusion': []}
    for k, lat in enumerate((0.012, 0.011)):
        t = T0 + k * 1.0 / rtf
        for cam in ('cam1', 'cam2'):
            calls[cam].append([t, t + 0.010, 0.006, f'timer {cam}_camera fire'])
            calls[cam].append([t + 0.009, t + 0.0095, 0.0005, OBSERVATION])
        done = t + lat / rtf
        calls['fusion'].append([done - 0.001, done, 0.0008, 'sub fusion marker_observations'])
        calls['fusion'].append([done - 0.0002, done - 0.0001, 0.0001, ESTIMATE])
    d = tmp_path / 'run' / 'logs' / 'callbacks'
    d.mkdir(parents=True)
    for process, c in calls.items():
        (d / f'{process}.trace').write_text(json.dumps({'process': f'/{process}', 'calls': c}))
    (d / 'broken.trace').write_text('{not json')
    demands = [
        {'index': 0, 'timing': {'estimate': 0.012 - 0.0002}},
        {'index': 1, 'timing': {'estimate': None}},
        {'index': 2, 'timing': {'estimate': 0.011 - 0.0002}},
    ]
    (tmp_path / 'run' / 'results.json').write_text(
        json.dumps({'set': 'A', 'system': 'fast', 'demands': demands})
    )
    return tmp_path / 'run'


def test_demands_are_placed_by_fusions_estimates(tmp_path: Path) -> None:
    run = _run(tmp_path)
    traces = load_traces(run / 'logs' / 'callbacks')
    assert sorted(traces) == ['cam1', 'cam2', 'fusion']  # the broken file skipped
    doc = json.loads((run / 'results.json').read_text())
    windows = demand_windows(doc['demands'], traces)
    assert [w.index for w in windows] == [0, 2]
    assert windows[0].instant == pytest.approx(T0, abs=1e-9)
    assert windows[1].instant == pytest.approx(T0 + 1.0, abs=1e-9)
    # At rtf 2 the simulated seconds after the instant are half as many wall seconds.
    fast = _run(tmp_path / 'fast', rtf=2.0)
    traces2 = load_traces(fast / 'logs' / 'callbacks')
    doc2 = json.loads((fast / 'results.json').read_text())
    assert demand_windows(doc2['demands'], traces2, 2.0)[1].instant == pytest.approx(T0 + 0.5)
    # One estimate too few: nothing is placed rather than the wrong demands.
    traces['fusion'] = traces['fusion'][:-1]
    assert demand_windows(doc['demands'], traces) == []


def test_occupancy_counts_the_cpu_inside_the_window(tmp_path: Path) -> None:
    traces = load_traces(_run(tmp_path) / 'logs' / 'callbacks')
    # The cameras' 6 ms each, the half of each call inside [T0 + 5 ms, T0 + 10 ms]: 3 ms each;
    # publishes are inside their callbacks and not counted again.
    assert occupancy(traces, T0 + 0.005, T0 + 0.010) == pytest.approx(0.006, abs=1e-6)
    assert occupancy(traces, T0 - 1.0, T0 - 0.5) == 0.0
    doc = json.loads((tmp_path / 'run' / 'results.json').read_text())
    rows = summarise(demand_windows(doc['demands'], traces), traces, cores=2)
    assert rows[0]['index'] == 0
    # Up to the estimate's publication, 11.8 ms: both cameras' 12 ms and fusion's callback's
    # 0.8 ms, four fifths of it inside.
    assert rows[0]['cpu_in_window_ms'] == pytest.approx(12.0 + 0.64, abs=0.01)
    assert rows[0]['occupancy'] == pytest.approx(12.64 / (2 * 11.8), abs=1e-3)


def test_write_timeline_draws_the_median_demand(tmp_path: Path) -> None:
    run = _run(tmp_path)
    png = write_timeline(run, cores=2)
    assert png == run / 'timeline.png'
    assert png.stat().st_size > 10_000
    summary = json.loads((run / 'timeline.json').read_text())
    assert [r['index'] for r in summary['demands']] == [0, 2]
    assert summary['cores'] == 2
    assert 0.4 < summary['median_occupancy'] < 0.7
    # Without traces there is nothing to draw, and nothing is written.
    bare = tmp_path / 'bare'
    bare.mkdir()
    (bare / 'results.json').write_text(json.dumps({'demands': []}))
    assert write_timeline(bare, cores=2) is None
    assert not (bare / 'timeline.json').exists()
