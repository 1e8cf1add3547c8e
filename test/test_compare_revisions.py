"""scripts/compare_revisions.py: its figures from run directories, its ratios, its refusals
(the runs themselves start graphs; docs/performance.md has a measured comparison)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'scripts'))

from compare_revisions import (  # noqa: E402
    RunFigures,
    main,
    read_run,
    summarise,
    tree_cpu_seconds,
)

pytestmark = pytest.mark.meta


def _run_dir(tmp: Path, name: str, cores: float, latencies: list[float | None]) -> Path:
    d = tmp / name
    d.mkdir()
    (d / 'cpu.json').write_text(json.dumps({'cores': cores, 'wall_seconds': 10.0}))
    demands = [{'index': i, 'latency': x} for i, x in enumerate(latencies)]
    (d / 'results.json').write_text(json.dumps({'demands': demands}))
    return d


def test_a_runs_figures_come_from_its_cpu_and_results(tmp_path: Path) -> None:
    d = _run_dir(tmp_path, 'new_0', 0.4, [0.010, None, 0.020])
    fig = read_run('new', d, 40.0)
    assert fig.cores == pytest.approx(0.4)
    assert fig.latencies_ms == pytest.approx([10.0, 20.0])  # a demand without one is left out
    assert fig.latency_ms == pytest.approx(15.0)


def test_a_run_without_its_files_is_refused(tmp_path: Path) -> None:
    d = tmp_path / 'broken'
    d.mkdir()
    with pytest.raises(ValueError, match=r'cpu\.json'):
        read_run('old', d, 1.0)
    (d / 'cpu.json').write_text('{}')
    (d / 'results.json').write_text('{"demands": []}')
    with pytest.raises(ValueError, match='"cores"'):
        read_run('old', d, 1.0)


def test_the_ratios_are_the_new_medians_over_the_old() -> None:
    runs = [
        RunFigures('old', 0.6, [40.0, 50.0], 1.0),
        RunFigures('old', 0.8, [60.0], 1.0),
        RunFigures('new', 0.3, [10.0, 20.0], 1.0),
        RunFigures('new', 0.3, [30.0], 1.0),
    ]
    s = summarise(runs)
    assert s['old']['cores_median'] == pytest.approx(0.7)
    assert s['new']['latency_ms_median'] == pytest.approx(20.0)
    assert s['cores_median_new_to_old'] == pytest.approx(0.3 / 0.7, abs=1e-3)
    assert s['latency_ms_median_new_to_old'] == pytest.approx(0.4)


def test_bad_arguments_are_refused_before_any_run(tmp_path: Path) -> None:
    out = tmp_path / 'exists'
    out.mkdir()
    with pytest.raises(SystemExit):
        main(['--old', str(tmp_path), '--out', str(out)])
    with pytest.raises(SystemExit, match='make setup'):
        main(['--old', str(tmp_path), '--out', str(tmp_path / 'new')])
    assert not (tmp_path / 'new').exists()


def test_a_process_trees_cpu_counts_its_children() -> None:
    spin = 'import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass\n'
    child = subprocess.Popen([sys.executable, '-c', spin + 'time.sleep(5)'])
    try:
        deadline = time.monotonic() + 10.0
        while tree_cpu_seconds(child.pid) < 0.25 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert tree_cpu_seconds(child.pid) >= 0.25
        assert tree_cpu_seconds(os.getpid()) >= tree_cpu_seconds(child.pid)
    finally:
        child.kill()
        child.wait()
