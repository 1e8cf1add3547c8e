"""Reliability: nodes killed mid-run and restarted (issue 8, point 2).

One graph run of Set A with the fast system loses, with SIGKILL, an imager (restarted 2.5 s
later), a stage node (restarted) and the fusion node (restarted). The dispatcher must notice
the dead camera within one service interval (1 s of demands) and dispatch without it, the
restarted nodes must rejoin, and every demand instant must end with an estimate or an explicit
failure record.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
SERVICE_INTERVAL = 1.0  # s between demand instants (experiments.yaml)
# When the killed stage is restarted: early enough that it has rejoined before the run ends on
# a busy machine (at 8.2 s a clean-clone run once ended with cam4 still starting).
STAGE_BACK = 7.6


@pytest.mark.graph
@pytest.mark.slow
def test_killed_nodes_are_noticed_and_rejoin(tmp_path: Path) -> None:
    out = tmp_path / 'run'
    kills = ['cam1_imager@3.2:5.7', f'cam4_stage@6.2:{STAGE_BACK}', 'fusion@8.6:9.4']
    cmd = [ACTIVESURV, 'experiment', '--set', 'A', '--system', 'fast', '--out', str(out)]
    # Half real time: a killed node's process takes 2-4 s of wall time to start again, and at
    # rtf 1 the run may end before the restarted stage has rejoined.
    cmd += ['--seed', '3', '--rtf', '0.5']
    for k in kills:
        cmd += ['--kill', k]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert 'killed cam1_imager' in r.stdout, r.stdout
    assert 'restarted fusion' in r.stdout, r.stdout

    doc = json.loads((out / 'results.json').read_text())
    demands = doc['demands']
    assert len(demands) == 10
    # Never silence: each demand has an estimate or a failure status with a reason.
    for d in demands:
        assert d['status'] not in ('', None), d
        assert d['estimated_position'] is not None or d['reason'], d
    assert sum(d['estimated_position'] is not None for d in demands) >= 8

    # The dispatcher's diagnostics (published at once when a camera goes down or comes back)
    # say when each camera was dropped and that it rejoined.
    from activesurv_common.ros.conversions import time_to_sec
    from activesurv_common.ros.diagnostics import values_of
    from activesurv_recording.bagio import read_bag

    history = []
    for m in read_bag(out / 'bag', {'/diagnostics'}):
        values = values_of(m.msg, 'activesurv/dispatcher')
        if values is not None:
            history.append((time_to_sec(m.msg.header.stamp), values))
    assert history, 'no dispatcher diagnostics in the bag'

    def first_down(camera: str, after: float) -> float | None:
        # A camera whose process is busy for a moment may be dropped and re-admitted before
        # its kill (seen once: cam4 out for 0.2 s at the first demand); the kill is the drop
        # after its instant.
        return next((t for t, v in history if t >= after and camera in v['cameras_down']), None)

    t_lost = first_down('cam1', 3.2)
    assert t_lost is not None, history[-1]
    assert 3.2 <= t_lost <= 3.2 + SERVICE_INTERVAL, t_lost
    t_stage_lost = first_down('cam4', 6.2)
    assert t_stage_lost is not None
    assert 6.2 <= t_stage_lost <= 6.2 + SERVICE_INTERVAL
    final = history[-1][1]
    assert final['cameras_down'] == '[]', 'a restarted camera did not rejoin'
    assert int(final['cameras_back']) >= 2, final
    assert int(final['cameras_lost']) >= 2, final
    # Cameras are not asked to capture while they are known to be dead.
    for d in demands:
        t = d['t']
        if t_lost + 0.3 < t < 5.7:
            assert 'cam1' not in d['assigned'], d
        if t_stage_lost + 0.3 < t < STAGE_BACK:
            assert 'cam4' not in d['assigned'], d
    # The demands around the fusion restart are answered by the new fusion node.
    around = [d for d in demands if 8.0 <= d['t'] <= 10.0]
    assert around
    # ... and none twice: the fusion journal survives the kill.
    answered = [m.msg.demand_index for m in read_bag(out / 'bag', {'/target_estimate'})]
    assert sorted(answered) == sorted(set(answered)), answered
    assert all(d['status'] != 'not_captured' for d in around), around
