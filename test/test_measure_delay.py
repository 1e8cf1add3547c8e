"""``activesurv hardware measure-delay`` on the lab: cameras whose true delay and clock the lab's
hardware file does not know (``--exposure-delay``, ``--clock-offset``) are measured within 2 ms,
written to ``CALDIR/delays.yaml``, and a hardware run then uses them."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from activesurv_bringup.rig.hardware import calibration_dir, read
from activesurv_bringup.rig.rigs import nominal
from activesurv_hardware.delays import with_measured_delays
from activesurv_sim.rig import save_rig

pytestmark = [pytest.mark.graph, pytest.mark.slow]

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def test_measure_delay_finds_what_the_file_does_not_know(
    tmp_path: Path, wait_for_file: Callable[..., bool]
) -> None:
    rig = tmp_path / 'rig.yaml'
    save_rig(nominal(), rig)
    cal = tmp_path / 'cal'
    nominal().truth().save(cal)  # the lab's rig is the nominal one: its exact calibration
    lab_dir = tmp_path / 'lab'
    lab = subprocess.Popen(
        [ACTIVESURV, 'lab', '--rig', str(rig), '--out', str(lab_dir), '--cameras', 'cam1',
         '--exposure-delay', 'cam1=0.045', '--exposure-delay', 'overhead=0.012',
         '--clock-offset', 'cam1=0.005'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    hw = lab_dir / 'hardware.yaml'
    try:
        assert wait_for_file(hw, lab)
        r = subprocess.run(
            [ACTIVESURV, 'hardware', 'measure-delay', '--hardware', str(hw), '--calibration',
             str(cal), '--cameras', 'cam1,overhead', '--yes'],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
    finally:
        lab.send_signal(signal.SIGINT)
        lab.communicate(timeout=60)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    doc = yaml.safe_load((cal / 'delays.yaml').read_text())
    # The file says 20 ms for every camera; the truth is 45 + 5 (clock) and 12 ms.
    assert doc['cam1']['exposure_delay'] == pytest.approx(0.050, abs=0.002), doc
    assert doc['overhead']['exposure_delay'] == pytest.approx(0.012, abs=0.002), doc
    assert doc['cam1']['samples'] >= 30
    assert 0.001 < doc['cam1']['jitter'] < 0.004, doc  # the lab's stamps: 2 ms std
    measured = with_measured_delays(read(hw), calibration_dir(read(hw), str(cal)), lambda _: None)
    assert measured.cameras['cam1'].exposure_delay == pytest.approx(0.050, abs=0.002)
    assert read(hw).cameras['cam1'].exposure_delay == pytest.approx(0.02)
