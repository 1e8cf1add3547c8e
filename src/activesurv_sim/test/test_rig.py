"""The rig file: nominal and perturbed rigs, their YAML, stage error maps, the true mount."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.mount import CameraMount
from activesurv_sim.rig import (
    AxisError,
    RigError,
    load_rig,
    nominal_rig,
    perturb_rig,
    rig_from_dict,
    rig_to_dict,
    rotary_error,
    save_rig,
)

MOUNTS = {
    'cam1': CameraMount('cam1', [-0.28, -0.42, 0.05], math.pi / 2, 0.0, [0, 0, 0], [1, 0, 0]),
    'cam2': CameraMount('cam2', [0.02, -0.5, 0.05], math.pi / 2),
}
BASE = {'mount': {'base': [0.0, -0.5, 0.05]}}
OVERHEAD = [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0]
OVER = {'pose': OVERHEAD}


def _flat(data: object) -> list[float]:
    if isinstance(data, dict):
        return [v for k in sorted(data) for v in [hash(k) % 997, *_flat(data[k])]]
    if isinstance(data, list):
        return [v for item in data for v in _flat(item)]
    return [float(data)] if isinstance(data, (int, float)) else [float(hash(str(data)) % 997)]


def test_nominal_rig_is_the_paper_hardware() -> None:
    rig = nominal_rig(MOUNTS, OVERHEAD)
    assert set(rig.cameras) == {'cam1', 'cam2'}
    assert np.allclose(rig.camera('cam1').camera.K, dynamic_camera('cam1').K)
    assert rig.camera('cam1').linear_accuracy == pytest.approx(30e-6)
    assert rig.camera('cam1').rotary_accuracy == pytest.approx(math.radians(10 / 3600))
    assert rig.table_accuracy == (48e-6, 24e-6)
    with pytest.raises(RigError, match='no camera'):
        rig.camera('cam9')


@pytest.mark.parametrize('seed', range(12))
def test_perturbed_rigs_stay_within_the_stated_bounds(seed: int) -> None:
    nom = nominal_rig(MOUNTS, OVERHEAD)
    rig = perturb_rig(nom, seed)
    assert rig.seed == seed
    assert rig.name == f'perturbed-{seed}'
    for cid, rc in rig.cameras.items():
        n = nom.camera(cid)
        assert abs(rc.camera.fx / n.camera.fx - 1) <= 0.02
        assert np.all(np.abs(rc.camera.K[:2, 2] - n.camera.K[:2, 2]) <= 15.0)
        assert abs(rc.camera.dist[0]) <= 0.1
        assert np.all(np.abs(rc.mount.base - n.mount.base) <= 3e-3)
        assert abs(rc.mount.yaw_offset - n.mount.yaw_offset) <= math.radians(1.0)
        assert abs(rc.mount.pitch - n.mount.pitch) <= math.radians(1.0)
        off = rc.mount.offset
        assert 5e-3 <= np.hypot(off[0], off[1]) <= 30e-3
        assert off[2] == 0.0
    # the same seed draws the same rig; another seed another one
    assert rig_to_dict(perturb_rig(nom, seed)) == rig_to_dict(rig)
    assert rig_to_dict(perturb_rig(nom, seed + 100)) != rig_to_dict(rig)


def test_a_rig_file_round_trips_with_the_contract_keys(tmp_path: Path) -> None:
    rig = perturb_rig(nominal_rig(MOUNTS, OVERHEAD), 4)
    path = tmp_path / 'rig.yaml'
    save_rig(rig, path)
    data = yaml.safe_load(path.read_text())
    cam = data['cameras']['cam1']
    for key in ('image_width', 'image_height', 'camera_matrix', 'distortion_coefficients'):
        assert key in cam['camera_info']
    assert cam['camera_info']['distortion_model'] == 'plumb_bob'
    assert len(cam['mount']['base']) == 3
    assert len(cam['mount']['rotation_centre_offset']) == 3
    back = load_rig(path)
    assert _flat(rig_to_dict(back)) == pytest.approx(_flat(rig_to_dict(rig)), abs=1e-15)
    # the rotation-centre offset is the platform offset in the optical frame at zero rotation
    m = back.camera('cam2').mount
    assert np.allclose(m.offset, rig.camera('cam2').mount.offset, atol=1e-12)
    T0 = m.camera_pose(0.0, 0.0)
    axis_point = m.base
    assert np.allclose(T0.R.T @ (T0.t - axis_point), m.rotation_centre_offset, atol=1e-12)


def test_a_value_given_in_a_rig_file_is_the_truth_and_the_rest_defaults() -> None:
    rig = rig_from_dict(
        {
            'cameras': {'cam2': {'mount': {'rotation_centre_offset': [0.01, 0.0, 0.0]}}},
            'overhead': {'pose': OVERHEAD},
        },
        MOUNTS,
    )
    m = rig.camera('cam2').mount
    assert np.allclose(m.base, MOUNTS['cam2'].base)
    assert np.allclose(m.rotation_centre_offset, [0.01, 0.0, 0.0])
    assert np.allclose(rig.camera('cam2').camera.K, dynamic_camera().K)


@pytest.mark.parametrize(
    ('data', 'match'),
    [
        ({}, 'cameras'),
        ({'cameras': {'cam1': BASE}}, 'overhead.pose'),
        ({'cameras': {'c': {'mount': {'base': [0, 0]}}}, 'overhead': OVER}, 'base'),
        ({'cameras': {'c': BASE}, 'overhead': {'pose': [0, 0, math.nan, 0, 0, 0, 1]}}, 'pose'),
        ({'cameras': {'c': {**BASE, 'stage_accuracy': {'rotary': -1}}}, 'overhead': OVER}, 'acc'),
        ({'cameras': {'c': {**BASE, 'camera_info': {'image_width': 6}}}, 'overhead': OVER}, 'cal'),
    ],
)  # fmt: skip
def test_a_bad_rig_is_refused_with_a_reason(data: object, match: str) -> None:
    with pytest.raises(RigError, match=match):
        rig_from_dict(data)


def test_stage_errors_are_bounded_repeatable_and_seeded() -> None:
    err = rotary_error(math.radians(10 / 3600), 3)
    q = np.linspace(-1.2, 1.2, 2001)
    e = np.array([err.error(float(v)) for v in q])
    assert np.max(np.abs(e)) <= err.accuracy + 1e-18
    assert np.max(np.abs(e)) > 0.3 * err.accuracy  # not negligible
    assert err.error(0.3) == rotary_error(err.accuracy, 3).error(0.3)
    assert err.error(0.3) != rotary_error(err.accuracy, 4).error(0.3)
    assert AxisError(0.0, (1.0,)).error(0.5) == 0.0
    with pytest.raises(RigError):
        AxisError(-1.0, (1.0,))


def test_the_true_mount_is_where_the_stages_really_are() -> None:
    rc = perturb_rig(nominal_rig(MOUNTS, OVERHEAD), 2).camera('cam1')
    true = rc.true_mount()
    q = np.array([0.12, 0.4])
    reported = rc.mount.pose_from_joints(q)
    real = true.pose_from_joints(q)
    # within Table I: 30 um along the axis plus 10 arcsec about it (at the offset's radius)
    dt = np.linalg.norm(real.t - reported.t)
    assert 0.0 < dt <= 30e-6 + np.linalg.norm(rc.mount.offset) * rc.rotary_accuracy + 1e-12
    angle = math.acos(min(1.0, (np.trace(real.R.T @ reported.R) - 1) / 2))
    assert angle <= rc.rotary_accuracy + 1e-9
    assert true.joint_names == rc.mount.joint_names == ('cam1_x', 'cam1_yaw')
