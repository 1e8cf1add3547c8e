"""``activesurv commission --live --hardware`` against an emulated lab (``activesurv lab``): the
lab's hardware file names emulated Zaber and GRBL controllers on pseudo-terminals and
free-running camera drivers of a perturbed rig; commissioning starts the stage bridges from the
file and knows only the topics, as with real hardware."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from activesurv_bringup.rig.rigs import nominal
from activesurv_common.calibration import load_calibration
from activesurv_sim.rig import load_rig, perturb_rig, save_rig

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
pytestmark = [pytest.mark.graph, pytest.mark.slow]


def test_live_commissioning_through_serial_controllers(
    tmp_path: Path, wait_for_file: Callable[..., bool]
) -> None:
    rig_file, cal = tmp_path / 'rig.yaml', tmp_path / 'cal'
    save_rig(perturb_rig(nominal(), 12), rig_file)
    lab = subprocess.Popen(
        [ACTIVESURV, 'lab', '--rig', str(rig_file), '--out', str(tmp_path / 'lab'),
         '--cameras', 'cam1'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    hw = tmp_path / 'lab' / 'hardware.yaml'
    try:
        assert wait_for_file(hw, lab), 'the lab wrote no hardware file'
        r = subprocess.run(
            [ACTIVESURV, 'commission', '--live', '--yes', '--hardware', str(hw), '--out', str(cal),
             '--stations', '4'],  # a quick check: 4 of cam1's 16 stations
            capture_output=True, text=True, timeout=900,
        )  # fmt: skip
    finally:
        lab.send_signal(signal.SIGINT)
        out, err = lab.communicate(timeout=60)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert lab.returncode == 0, out[-1000:] + err[-2000:]
    assert 'lab up' in out
    assert 'lab stopped' in out
    logs = cal / 'work' / 'logs'  # commissioning started the bridges from the hardware file
    assert 'zaber controller on' in (logs / 'cam1_bridge.log').read_text()
    assert 'grbl controller on' in (logs / 'xy_table_bridge.log').read_text()
    doc = json.loads((cal / 'commission.json').read_text())
    cam = doc['cameras']['cam1']
    assert cam['commissioned']
    assert cam['stations'] == 4
    assert cam['reprojection_rms_px'] < 0.3
    assert 'error' not in cam  # live: nothing knows the truth
    # ... which the test does: the calibration against the rig the cameras simulate.
    rig, c = load_rig(rig_file), load_calibration(cal)
    truth = rig.camera('cam1')
    assert abs(c.cameras['cam1'].fx / truth.camera.fx - 1.0) < 2e-3
    assert np.max(np.abs(c.mounts['cam1'].base - truth.mount.base)) < 1e-3
    assert np.max(np.abs(c.mounts['cam1'].offset - truth.mount.offset)) < 1e-3
