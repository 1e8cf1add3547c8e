"""Mount kinematics, Appendix C rotation centre, OpenCV calibration, sensor model (no ROS)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from activesurv_common.camera_model import CameraModel, overhead_camera
from activesurv_common.geometry import Transform, rot_x, rot_y
from activesurv_common.mount import CameraMount, solve_rotation_centre
from activesurv_common.sensor_model import SensorModel, view_geometry
from activesurv_common.timeseries import FrameBuffer, TimeSeries
from activesurv_imaging.calibration import (
    board_pose,
    calibrate_intrinsics,
    camera_extrinsics,
    mount_from_extrinsics,
)
from activesurv_imaging.errors import CalibrationError, SensorModelError
from activesurv_sim.render import Plate, Scene, SensorNoise, look_at, render
from activesurv_studies.sensor_model_experiment import fit_model, run_experiment

MOUNT = CameraMount(
    'cam1',
    base=[0.1, -0.5, 0.05],
    yaw_offset=math.pi / 2,
    pitch=0.05,
    offset=[0.025, -0.01, 0.02],
    linear_axis=[1.0, 0.0, 0.0],
)


def test_mount_kinematics() -> None:
    assert MOUNT.joint_names == ('cam1_x', 'cam1_yaw')
    T0 = MOUNT.camera_pose(0.0, 0.0)
    T1 = MOUNT.camera_pose(0.1, 0.0)
    assert np.allclose(T1.t - T0.t, [0.1, 0.0, 0.0])
    # Optical axis along +y world (yaw_offset 90 deg), tilted down by the pitch.
    assert np.allclose(T0.R[:, 2], [0.0, math.cos(0.05), -math.sin(0.05)], atol=1e-12)
    # Turning the rotary stage swings the camera centre around the axis by the offset.
    T2 = MOUNT.camera_pose(0.0, 0.3)
    axis_xy = MOUNT.base[:2]
    assert np.linalg.norm(T2.t[:2] - axis_xy) == pytest.approx(np.linalg.norm(MOUNT.offset[:2]))
    assert np.allclose(MOUNT.camera_pose_from_joints(['cam1_yaw', 'cam1_x'], [0.3, 0.0]).t, T2.t)
    with pytest.raises(CalibrationError, match='cam1_x'):
        MOUNT.camera_pose_from_joints(['cam1_yaw'], [0.0])
    with pytest.raises(CalibrationError, match='finite'):
        MOUNT.camera_pose(float('nan'), 0.0)


@pytest.mark.parametrize('angles', [[0.2], [0.1, -0.15, 0.25]])
def test_rotation_centre_eq_c1(angles: list[float]) -> None:
    target = np.array([0.12, 0.05, 0.07])
    rng = np.random.default_rng(1)
    before = np.array([MOUNT.camera_pose(0, 0).inverse().apply(target) for _ in angles])
    after = np.array([MOUNT.camera_pose(0, a).inverse().apply(target) for a in angles])
    centre = solve_rotation_centre(
        before + rng.normal(0, 1e-7, before.shape), after, angles, pitch=MOUNT.pitch
    )
    assert np.allclose(-centre, MOUNT.offset[:2], atol=2e-5)
    with pytest.raises(CalibrationError, match='too small'):
        solve_rotation_centre(before, before, np.zeros(len(angles)))


def test_rotation_centre_command(tmp_path: Path) -> None:
    target = np.array([0.12, 0.05, 0.07])
    b = MOUNT.camera_pose(0, 0).inverse().apply(target)
    a = MOUNT.camera_pose(0, math.radians(12)).inverse().apply(target)
    (tmp_path / 'b.csv').write_text('x,y,z\n' + ','.join(map(str, b)) + '\n')
    (tmp_path / 'a.csv').write_text(','.join(map(str, a)) + '\n')
    out = tmp_path / 'offset.yaml'
    exe = Path(sys.executable).parent / 'activesurv_calibrate'
    r = subprocess.run(
        [
            str(exe),
            'rotation-centre',
            '--before',
            str(tmp_path / 'b.csv'),
            '--after',
            str(tmp_path / 'a.csv'),
            '--angle-deg',
            '12',
            '--pitch-deg',
            str(math.degrees(MOUNT.pitch)),
            '--out',
            str(out),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    data = yaml.safe_load(out.read_text())
    assert np.allclose(data['camera_offset_platform_xy'], MOUNT.offset[:2], atol=1e-6)
    bad = subprocess.run(
        [
            str(exe),
            'rotation-centre',
            '--before',
            str(tmp_path / 'none.csv'),
            '--after',
            str(tmp_path / 'a.csv'),
            '--angle-deg',
            '12',
            '--out',
            str(out),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert bad.returncode == 1
    assert 'cannot read' in bad.stderr
    assert 'Traceback' not in bad.stderr


def _board_views(camera: CameraModel, n: int, seed: int) -> list[np.ndarray]:
    board = Plate.checkerboard([0, 0, 0], [0, 0, 1], [1, 0, 0], (9, 6), 0.03)
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        az = 2 * math.pi * k / n
        direction = rot_x(0.6 * math.cos(az)) @ rot_y(0.6 * math.sin(az)) @ np.array([0, 0, -1.0])
        T = look_at(0.9 * direction, rng.normal(0, 0.01, 3), up=(0, 1, 0))
        out.append(render(camera, T, Scene((board,)), SensorNoise(supersample=3), rng))
    return out


def test_intrinsic_and_extrinsic_calibration_of_the_overhead_camera() -> None:
    truth = CameraModel(640, 480, overhead_camera().K, [-0.08, 0.0, 0.0, 0.0, 0.0], 'overhead')
    cam, rms = calibrate_intrinsics(_board_views(truth, 8, 2), (9, 6), 0.03, 'overhead')
    assert rms < 0.3
    assert cam.fx == pytest.approx(truth.fx, rel=0.01)
    assert cam.dist[0] == pytest.approx(-0.08, abs=0.03)
    # Extrinsics: a board lying on the table at a known world pose, seen from above. Its frame
    # follows OpenCV: z points away from the camera, so down here.
    T_wb = Transform.from_rt(np.diag([1.0, -1.0, -1.0]), [0.25, 0.1, 0.0])
    T_wc = look_at([0.35, 0.0, 1.0], [0.25, 0.1, 0.0], up=(0, 1, 0))
    board = Plate.checkerboard(T_wb.t, T_wb.R[:, 2], T_wb.R[:, 0], (9, 6), 0.03)
    img = render(
        truth, T_wc, Scene((board,)), SensorNoise(supersample=3), np.random.default_rng(3)
    )
    est = camera_extrinsics(T_wb, board_pose(img, truth, (9, 6), 0.03))
    # One view at 1 m: a few mrad of rotation error move the centre by a few mm.
    assert np.linalg.norm(est.t - T_wc.t) < 6e-3
    assert np.allclose(est.R, T_wc.R, atol=1e-2)
    # The mount's offset and pitch from extrinsics at known joint positions.
    nominal = CameraMount('cam1', [0.1, -0.5, 0.05], math.pi / 2, 0.0, [0, 0, 0], [1, 0, 0])
    recovered = mount_from_extrinsics(nominal, MOUNT.camera_pose(0.07, 0.2), 0.07, 0.2)
    assert np.allclose(recovered.offset, MOUNT.offset, atol=1e-9)
    assert recovered.pitch == pytest.approx(MOUNT.pitch)


def test_sensor_model_experiment_and_yaml(tmp_path: Path) -> None:
    cells = run_experiment(
        [0.45, 0.6, 0.75], [math.radians(b) for b in (5, 30, 55)], repetitions=4, seed=5
    )
    assert len(cells) == 9
    model = fit_model(cells)
    model.save(tmp_path / 'm.yaml')
    back = SensorModel.load(tmp_path / 'm.yaml')
    assert np.allclose(back.coefficients, model.coefficients)
    # Depth (z) is the worst position variable, and it grows with distance.
    v_near, v_far = back.variances(0.45, 0.5), back.variances(0.75, 0.5)
    assert v_near[2] > v_near[0]
    assert v_far[2] > v_near[2]
    (tmp_path / 'bad.yaml').write_text('sensor_model: {variables: []}\n')
    with pytest.raises(SensorModelError, match='malformed'):
        SensorModel.load(tmp_path / 'bad.yaml')
    with pytest.raises(SensorModelError, match='finite'):
        back.variances(float('nan'), 0.1)


def test_packaged_model_and_view_geometry() -> None:
    model = SensorModel.load()
    assert model.covariance(0.6, 0.7).shape == (6, 6)
    R = rot_x(0.3)
    w = model.world_covariance(0.6, 0.7, R)
    assert np.linalg.norm(w) == pytest.approx(np.linalg.norm(model.covariance(0.6, 0.7)))
    cam = overhead_camera('cam1')
    T = look_at([0.0, -0.6, 0.0], [0.0, 0.0, 0.0])
    g = view_geometry(cam, T, [0, 0, 0], [0, -1, 0], 0.0125)
    assert g.in_view
    assert g.distance == pytest.approx(0.6)
    assert g.bearing == pytest.approx(0.0)
    behind = view_geometry(cam, T, [0, 0, 0], [0, 1, 0], 0.0125)
    assert not behind.in_view  # marker faces away
    off = view_geometry(cam, T, [0.5, 0, 0], [0, -1, 0], 0.0125)
    assert not off.in_view


def test_timeseries_and_frames() -> None:
    ts = TimeSeries(2)
    assert ts.add(1.0, [0.0, 0.0])
    assert ts.add(2.0, [1.0, 2.0])
    assert not ts.add(3.0, [np.nan, 0.0])
    assert np.allclose(ts.at(1.5), [0.5, 1.0])
    assert ts.at(2.05) is None
    assert np.allclose(ts.at(2.05, hold=0.1), [1.0, 2.0])
    fb: FrameBuffer[str] = FrameBuffer(3)
    for t in (1.0, 2.0, 3.0, 4.0):
        fb.add(t, f'f{t}')
    assert fb.closest(2.9, 0.2) == (3.0, 'f3.0')
    assert fb.closest(1.0, 0.2) is None  # evicted
