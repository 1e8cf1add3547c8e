"""Calibration directories: what the system believes, written and read back."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from activesurv_common.calibration import Calibration, load_calibration, pose_from_list
from activesurv_common.camera_model import dynamic_camera, overhead_camera
from activesurv_common.errors import CalibrationError
from activesurv_common.mount import CameraMount, mount_from_dict, mount_to_dict


def _calibration() -> Calibration:
    m1 = CameraMount('cam1', [0.1, -0.4, 0.05], 1.5, 0.01, [0.01, 0.02, 0.0], [1, 0, 0])
    m2 = CameraMount('cam2', [0.2, -0.5, 0.05], 1.6, -0.01, [0.0, -0.015, 0.0])
    return Calibration(
        'test',
        {'cam1': dynamic_camera('cam1'), 'cam2': dynamic_camera('cam2')},
        {'cam1': m1, 'cam2': m2},
        overhead_camera(),
        pose_from_list([0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0]),
    )


def test_a_calibration_round_trips_through_its_directory(tmp_path: Path) -> None:
    cal = _calibration()
    written = cal.save(tmp_path / 'cal')
    names = sorted(p.name for p in written)
    assert 'cam1.yaml' in names
    assert 'cam1_mount.yaml' in names
    assert 'overhead_pose.yaml' in names
    mount_file = yaml.safe_load((tmp_path / 'cal' / 'cam2_mount.yaml').read_text())
    assert set(mount_file['mount']) >= {'base', 'rotation_centre_offset', 'yaw_offset', 'pitch'}
    back = load_calibration(tmp_path / 'cal')
    for cid in ('cam1', 'cam2'):
        a, b = cal.mounts[cid], back.mounts[cid]
        assert np.allclose(a.base, b.base)
        assert np.allclose(a.offset, b.offset)
        assert a.yaw_offset == pytest.approx(b.yaw_offset)
        assert (a.linear_axis is None) == (b.linear_axis is None)
        assert np.allclose(cal.cameras[cid].K, back.cameras[cid].K)
    assert np.allclose(back.overhead_pose.t, cal.overhead_pose.t)


def test_missing_or_malformed_calibrations_are_refused(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match='does not exist'):
        load_calibration(tmp_path / 'none')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(CalibrationError, match=r'_mount\.yaml'):
        load_calibration(tmp_path / 'empty')
    _calibration().save(tmp_path / 'cal')
    (tmp_path / 'cal' / 'cam2.yaml').unlink()
    with pytest.raises(CalibrationError, match=r'cam2\.yaml'):
        load_calibration(tmp_path / 'cal')
    with pytest.raises(CalibrationError, match='7 finite'):
        pose_from_list([0.0] * 6)


def test_mount_mappings_accept_either_offset_form() -> None:
    m = CameraMount('c', [0, 0, 0], 0.3, math.radians(2), [0.01, -0.02, 0.0])
    d = mount_to_dict(m)
    assert np.allclose(mount_from_dict('c', d).offset, m.offset)
    legacy = {
        'base': [0, 0, 0],
        'yaw_offset': 0.3,
        'pitch': math.radians(2),
        'offset': [0.01, -0.02, 0],
    }
    assert np.allclose(mount_from_dict('c', legacy).offset, m.offset)
    with pytest.raises(CalibrationError, match='base'):
        mount_from_dict('c', {'yaw_offset': 0.0})
