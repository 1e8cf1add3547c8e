"""``activesurv commission`` through the node graph: simulated stages, table and cameras play a
perturbed rig; the commissioner knows only nominal values and what the cameras see."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from activesurv_bringup.rig.choice import choose
from activesurv_bringup.rig.commission import plane_mapping_error
from activesurv_bringup.rig.rigs import calibration_dir, nominal
from activesurv_common.calibration import load_calibration
from activesurv_sim.rig import perturb_rig, save_rig

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
# The commissioning fixture runs the node graph for about a minute.
pytestmark = [pytest.mark.graph, pytest.mark.slow]


@pytest.fixture(scope='module')
def commissioned(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp('commission')
    rig = root / 'rig.yaml'
    save_rig(perturb_rig(nominal(), 11), rig)
    out = root / 'cal'
    cmd = [ACTIVESURV, 'commission', '--rig', str(rig), '--out', str(out), '--cameras', 'cam3']
    cmd += ['--stations', '3']  # of cam3's 6: the accuracy holds (measured on three rigs)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    assert 'cam3:' in r.stdout
    assert 'overhead' in r.stdout
    return rig, out


def test_commissioning_writes_the_calibration_files(commissioned: tuple[Path, Path]) -> None:
    _, out = commissioned
    for name in ('cam3.yaml', 'cam3_mount.yaml', 'overhead.yaml', 'overhead_pose.yaml'):
        assert (out / name).is_file(), name
    info = yaml.safe_load((out / 'cam3.yaml').read_text())
    assert info['distortion_model'] == 'plumb_bob'
    assert info['image_width'] == 640
    mount = yaml.safe_load((out / 'cam3_mount.yaml').read_text())['mount']
    assert len(mount['base']) == 3
    assert len(mount['rotation_centre_offset']) == 3
    doc = json.loads((out / 'commission.json').read_text())
    assert isinstance(doc['cameras']['cam3']['reprojection_rms_px'], float)
    assert doc['cameras']['cam1']['commissioned'] is False  # not asked for: nominal values
    cal = load_calibration(out)
    assert set(cal.cameras) == {'cam1', 'cam2', 'cam3', 'cam4'}


def test_the_commissioned_values_match_the_rig(commissioned: tuple[Path, Path]) -> None:
    rig_file, out = commissioned
    doc = json.loads((out / 'commission.json').read_text())
    cam = doc['cameras']['cam3']
    assert cam['reprojection_rms_px'] < 0.3
    err = cam['error']
    assert err['focal_length_relative'] < 2e-3  # nominal is up to 2 % off
    assert err['base_m'] < 1e-3
    assert err['rotation_centre_offset_m'] < 1e-3
    assert err['pixel_error_px'] < 1.0
    assert doc['overhead']['error']['table_mapping_m'] < 0.5e-3
    # against the nominal values, which are centimetres off
    from activesurv_sim.rig import load_rig

    rig, nom = load_rig(rig_file), nominal()
    before = plane_mapping_error(
        rig.overhead, rig.overhead_pose, nom.overhead, nom.overhead_pose, 0.08
    )
    assert before > 5e-3


def test_the_report_shows_the_commissioning_quality(commissioned: tuple[Path, Path]) -> None:
    from activesurv_evaluation.report import calibration_section

    _, out = commissioned
    cam = json.loads((out / 'commission.json').read_text())['cameras']['cam3']
    sx, sy = cam['std']['principal_point_px']
    assert 0.0 < sx < 5.0  # what the views carry of it
    assert 0.0 < sy < 10.0
    assert 0.0 < cam['corner_noise_px'] < cam['sighting_noise_px'] < 0.5
    lines = calibration_section([{'calibration': str(out), 'rig': 'r', 'rig_source': 's'}])
    row = next(line for line in lines if line.startswith('| cam3 |'))
    cells = [c.strip() for c in row.strip('|').split('|')]
    assert cells[5] == f'{sx:.1f}, {sy:.1f}'
    assert float(cells[4]) == pytest.approx(cam['error']['principal_point_px'], abs=1e-3)
    assert next(line for line in lines if line.startswith('| cam1 |')).count('|') == 10


def test_a_run_uses_the_calibration_directory(commissioned: tuple[Path, Path]) -> None:
    rig_file, out = commissioned
    choice = choose(rig_file, str(out), 0)
    assert choice.calibration_source == str(out.resolve())
    assert not np.allclose(
        choice.calibration.mounts['cam3'].base, nominal().camera('cam3').mount.base
    )


def test_commission_refuses_what_it_cannot_do(
    tmp_path: Path, commissioned: tuple[Path, Path]
) -> None:
    rig_file, out = commissioned
    r = subprocess.run([ACTIVESURV, 'commission', '--out', str(tmp_path / 'x')],
                       capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 1
    assert '--live' in r.stderr
    r = subprocess.run([ACTIVESURV, 'commission', '--rig', str(rig_file), '--out', str(out)],
                       capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 1
    assert 'not empty' in r.stderr
    r = subprocess.run(
        [ACTIVESURV, 'commission', '--rig', str(rig_file), '--out', str(tmp_path / 'y'),
         '--cameras', 'cam9'], capture_output=True, text=True,
    )  # fmt: skip
    assert r.returncode == 1
    assert 'cam9' in r.stderr


def test_the_default_calibration_is_commissioned_once_per_rig(tmp_path: Path) -> None:
    rig = perturb_rig(nominal(), 4)
    d = calibration_dir(tmp_path, rig)
    assert d == calibration_dir(tmp_path, perturb_rig(nominal(), 4))
    assert d != calibration_dir(tmp_path, perturb_rig(nominal(), 5))
    assert d.parent == tmp_path / 'calibrations'
