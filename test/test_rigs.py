"""Runs on a rig: the simulator plays the rig's true hardware, every other node works from the
calibration it is given (issue 16)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from activesurv_bringup.cli import experiment
from activesurv_bringup.errors import ConfigError
from activesurv_bringup.experiments.experiment import load_experiment
from activesurv_bringup.experiments.graph import graph_specs
from activesurv_bringup.rig.choice import choose
from activesurv_bringup.rig.rigs import nominal
from activesurv_evaluation.results import summary

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
SIM_MODULES = ('activesurv_sim.sim_camera_node', 'activesurv_sim.xy_table_node')


@pytest.mark.cli
def test_rig_commands_write_nominal_and_perturbed_rigs(tmp_path: Path) -> None:
    nom, per = tmp_path / 'nominal.yaml', tmp_path / 'r7.yaml'
    subprocess.run([ACTIVESURV, 'rig', 'nominal', '--out', str(nom)], check=True)
    cmd = [ACTIVESURV, 'rig', 'perturb', '--in', str(nom), '--seed', '7', '--out', str(per)]
    subprocess.run(cmd, check=True)
    a, b = yaml.safe_load(nom.read_text()), yaml.safe_load(per.read_text())
    assert set(a['cameras']) == set(b['cameras']) == {'cam1', 'cam2', 'cam3', 'cam4'}
    assert a['cameras']['cam1']['camera_info']['camera_matrix']['data'][0] == 5000.0
    assert b['cameras']['cam1']['camera_info']['camera_matrix']['data'][0] != 5000.0
    assert b['rig']['seed'] == 7
    # a rig file is never overwritten
    again = subprocess.run(cmd, capture_output=True, text=True)
    assert again.returncode == 1
    assert 'exists' in again.stderr
    assert yaml.safe_load(per.read_text()) == b
    bad = tmp_path / 'bad.yaml'
    bad.write_text('cameras: [1, 2]\n')
    cmd = [ACTIVESURV, 'rig', 'perturb', '--in', str(bad), '--seed', '1', '--out', str(per) + '2']
    out = subprocess.run(cmd, capture_output=True, text=True)
    assert out.returncode == 1
    assert 'cameras' in out.stderr


@pytest.mark.cross
def test_only_the_simulator_reads_the_rig(tmp_path: Path) -> None:
    exp = load_experiment('A', 'fast', 3, rig=choose(None, 'nominal', 3))
    specs = graph_specs(exp, tmp_path / 'bag')
    readers = {s.module for s in specs if 'rig_file' in s.parameters}
    assert readers == set(SIM_MODULES)
    believed = yaml.safe_load((tmp_path / 'rig' / 'setup.yaml').read_text())
    nominal_base = nominal().camera('cam2').mount.base
    cam2 = next(c for c in believed['cameras'] if c['id'] == 'cam2')
    assert np.allclose(cam2['mount']['base'], nominal_base)  # told the nominal values
    truth = yaml.safe_load((tmp_path / 'rig' / 'rig.yaml').read_text())
    assert not np.allclose(truth['cameras']['cam2']['mount']['base'], nominal_base)
    cams = [s for s in specs if s.module == 'activesurv_sim.sim_camera_node']
    assert all(s.parameters['camera_info_file'].startswith(str(tmp_path)) for s in cams)


@pytest.mark.cross
def test_a_calibration_directory_is_used_as_given(tmp_path: Path) -> None:
    choice = choose(None, 'truth', 2)
    choice.calibration.save(tmp_path / 'cal')
    from_dir = choose(None, str(tmp_path / 'cal'), 2)
    for cid, m in choice.calibration.mounts.items():
        assert np.allclose(from_dir.calibration.mounts[cid].offset, m.offset)
        assert from_dir.calibration.mounts[cid].joint_names == m.joint_names
    with pytest.raises(ConfigError, match='calibration'):
        choose(None, str(tmp_path / 'missing'), 2)


@pytest.mark.cross
def test_truth_nominal_and_calibrated_runs_on_a_perturbed_rig(tmp_path: Path) -> None:
    docs = {}
    for cal in ('truth', 'nominal'):
        docs[cal] = experiment(
            'A', 'fast', tmp_path / cal, seed=5, mode='lockstep', calibration=cal, rig_seed=5
        )
        assert docs[cal]['rig'] == 'perturbed-5'
        assert docs[cal]['calibration'] == cal
    told = summary(docs['truth'])
    assert told['estimates'] == 10
    assert told['median_position_error'] < 0.2e-3
    # Told the nominal values, the cameras disagree by millimetres: fewer or worse estimates.
    guessed = summary(docs['nominal'])
    assert guessed['estimates'] < 10 or (
        guessed['median_position_error'] > 3 * told['median_position_error']
    )
