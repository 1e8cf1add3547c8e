"""The simulator's optics (issue 33): depth of field from a thin lens, motion streaks over the
exposure and a camera's gamma; in the rig file, validated."""

from __future__ import annotations

import math

import numpy as np
import pytest

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.mount import CameraMount
from activesurv_sim.frame_optics import FrameOptics
from activesurv_sim.lab_stats import LabCameraStats
from activesurv_sim.optics import Optics, OpticsError, frame_optics
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise, look_at
from activesurv_sim.rig import RigError, nominal_rig, rig_from_dict, rig_to_dict

CAM = dynamic_camera('cam1')  # fx 5000 px
QUIET = SensorNoise(0.8, 0.0, 0.0)


def _frame(distance: float, optics: FrameOptics, noise: SensorNoise = QUIET) -> np.ndarray:
    eye = np.array([0.0, -distance, 0.05])
    T = look_at(eye, [0.0, 0.0, 0.05])
    scene = Scene((Plate.disc([0.0, 0.0, 0.05], [0.0, -1.0, 0.0], 0.0125, 0.03),))
    return Renderer(CAM).render(T, scene, noise, np.random.default_rng(1), optics)


def _edge_width(row: np.ndarray) -> float:
    """Pixels the rim's ramp takes from 25 % to 75 % of the way up (the left rim)."""
    lo, hi = float(row.min()), float(row.max())
    x = np.arange(len(row))
    left = slice(0, int(np.argmax(row > (lo + hi) / 2)) + 30)
    r = row[left].astype(float)
    up25 = np.interp(lo + 0.25 * (hi - lo), r, x[left])
    up75 = np.interp(lo + 0.75 * (hi - lo), r, x[left])
    return float(up75 - up25)


def test_the_thin_lens_blur_circle() -> None:
    o = Optics(f_number=4.0, focus_distance=0.5, focal_length=0.025)
    assert o.defocus_sigma(5000.0, 0.5) == 0.0
    # c = (f / N) f |d - df| / (d (df - f)), in px (pitch f / fx), sigma = c / 4
    c = (0.025 / 4.0) * 0.025 * 0.05 / (0.45 * 0.475) / (0.025 / 5000.0)
    assert o.defocus_sigma(5000.0, 0.45) == pytest.approx(c / 4.0)
    near, far = o.depth_of_field(5000.0, max_sigma=1.0)
    assert o.defocus_sigma(5000.0, near) == pytest.approx(1.0)
    assert o.defocus_sigma(5000.0, far) == pytest.approx(1.0)
    wide = Optics(f_number=2.8, focus_distance=0.5)
    assert wide.defocus_sigma(5000.0, 0.45) > o.defocus_sigma(5000.0, 0.45)  # f/2.8 blurs more
    for bad in (
        {'f_number': 0.1},
        {'exposure_time': 0.0},
        {'gamma': 9.0},
        {'focus_distance': 0.01},
    ):
        with pytest.raises(OpticsError):
            Optics(**bad)  # type: ignore[arg-type]


def test_defocus_widens_the_rim_and_a_streak_smears_it_along_the_motion() -> None:
    sharp = _frame(0.5, FrameOptics())
    blurred = _frame(0.5, FrameOptics(defocus_sigma=3.0))
    v = sharp.shape[0] // 2
    assert _edge_width(blurred[v]) > 2.0 * _edge_width(sharp[v])
    streak = _frame(0.5, FrameOptics(streak=(12.0, 0.0)))
    # along u the rim's ramp is as long as the streak; across it (a column) it stays sharp
    assert _edge_width(streak[v]) == pytest.approx(0.5 * 12.0, abs=1.5)
    u = sharp.shape[1] // 2
    assert _edge_width(streak[:, u]) == pytest.approx(_edge_width(sharp[:, u]), abs=0.5)


def test_exposure_and_gamma_change_the_grey_levels() -> None:
    lin = _frame(0.5, FrameOptics())
    centre = (lin.shape[0] // 2, lin.shape[1] // 2)
    assert lin[centre] == pytest.approx(230, abs=2)  # the white disc at the reference exposure
    dim = _frame(0.5, FrameOptics(gain=0.5))
    assert dim[centre] == pytest.approx(115, abs=2)
    g = _frame(0.5, FrameOptics(gamma=2.2))
    assert g[centre] == pytest.approx(255 * (230 / 255) ** (1 / 2.2), abs=2)
    assert g[0, 0] == pytest.approx(255 * (70 / 255) ** (1 / 2.2), abs=2)  # background too


def test_frame_optics_of_a_moving_marker_and_a_turning_camera() -> None:
    o = Optics(focus_distance=0.5, exposure_time=0.01)
    T = look_at([0.0, -0.5, 0.05], [0.0, 0.0, 0.05])
    p = np.array([0.0, 0.0, 0.05])
    still = frame_optics(CAM, o, T, p)
    assert still.defocus_sigma == pytest.approx(0.0, abs=1e-9)
    assert still.streak == (0.0, 0.0)
    # the object at 20 mm/s along x for 10 ms: 0.2 mm, at 0.5 m and fx 5000: 2 px along u
    v = np.array([0.02, 0.0, 0.0])
    moving = frame_optics(CAM, o, T, p, ((T, p - 0.005 * v), (T, p + 0.005 * v)))
    assert math.hypot(*moving.streak) == pytest.approx(2.0, rel=0.02)
    assert abs(moving.streak[1]) < 0.05
    # a jump (the object entering from its parking place) leaves no streak
    far = frame_optics(CAM, o, T, p, ((T, p + [100.0, 100.0, 0.0]), (T, p)))
    assert far.streak == (0.0, 0.0)
    assert frame_optics(CAM, None, T, p) == FrameOptics()


def test_the_rig_file_carries_each_cameras_optics() -> None:
    mounts = {'cam1': _mount()}
    rig = nominal_rig(mounts, [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0])
    doc = rig_to_dict(rig)
    optics = doc['cameras']['cam1']['optics']
    assert optics['f_number'] == 4.0
    assert optics['exposure_time'] == 0.01
    assert optics['gamma'] == 1.0
    assert 0.3 < optics['focus_distance'] < 1.5  # the table's middle, seen from the mount
    assert doc['overhead']['optics']['focal_length'] == 0.012
    doc['cameras']['cam1']['optics'] = {'f_number': 2.8, 'gamma': 2.2}
    again = rig_from_dict(doc)
    assert again.camera('cam1').lens.f_number == 2.8
    assert again.camera('cam1').lens.focus_distance == optics['focus_distance']  # kept
    cal = again.truth().cameras['cam1']
    assert cal.gamma == 2.2  # what a perfect commissioning finds: the imager linearises
    assert cal.exposure_time == 0.01
    doc['cameras']['cam1']['optics'] = {'f_numbr': 2.8}
    with pytest.raises(RigError, match=r'cameras\.cam1\.optics\.f_numbr.*f_number'):
        rig_from_dict(doc)
    doc['cameras']['cam1']['optics'] = {'exposure_time': 2.0}
    with pytest.raises(RigError, match='exposure_time'):
        rig_from_dict(doc)


def _mount() -> CameraMount:
    return CameraMount('cam1', np.array([0.02, -0.5, 0.05]), 1.5708, 0.0, np.zeros(3))


def test_a_still_scene_is_rendered_once_and_only_its_noise_is_drawn_again() -> None:
    eye = np.array([0.0, -0.5, 0.05])
    T = look_at(eye, [0.0, 0.0, 0.05])
    scene = Scene((Plate.disc([0.0, 0.0, 0.05], [0.0, -1.0, 0.0], 0.0125, 0.03),))
    r = Renderer(CAM)
    rng = np.random.default_rng(3)
    fresh = Renderer(CAM).render(T, scene, QUIET, rng)
    assert np.array_equal(r.render(T, scene, QUIET, rng), fresh)
    assert np.array_equal(r.render(T, scene, QUIET, rng), fresh)  # the kept frame: the same
    noisy = SensorNoise(0.8, 40.0, 1.0)
    a, b = r.render(T, scene, noisy, rng), r.render(T, scene, noisy, rng)
    assert not np.array_equal(a, b)  # new noise on the kept frame
    assert abs(float(a.astype(float).mean()) - float(fresh.astype(float).mean())) < 0.5
    # Anything that moves is rendered anew: a plate 50 um aside, a camera turned, other optics.
    moved = Scene((Plate.disc([5e-5, 0.0, 0.05], [0.0, -1.0, 0.0], 0.0125, 0.03),))
    assert np.array_equal(r.render(T, moved, QUIET, rng), Renderer(CAM).render(T, moved, QUIET))
    turned = look_at(eye, [0.001, 0.0, 0.05])
    assert not np.array_equal(r.render(turned, scene, QUIET, rng), fresh)
    assert not np.array_equal(r.render(T, scene, QUIET, rng, FrameOptics(gain=0.5)), fresh)


def test_a_lab_camera_sees_the_object_while_it_is_reported_else_the_boards() -> None:
    from activesurv_common.camera_model import dynamic_camera as cam
    from activesurv_common.object_geometry import ObjectGeometry
    from activesurv_sim.sim_camera import OBJECT_GONE, SimulatedCamera, on_table

    T = look_at([0.0, -0.5, 0.05], [0.0, 0.0, 0.05])
    objects = SimulatedCamera(cam('cam1'), T, ObjectGeometry())
    boards = SimulatedCamera(cam('cam1'), T, ObjectGeometry())
    assert on_table(objects, boards, 10.0) is boards  # no object reported yet
    objects.objects.add(10.0, np.zeros(9))
    assert on_table(objects, boards, 10.5) is objects
    assert on_table(objects, boards, 9.0) is objects  # an exposure just before its first state
    assert on_table(objects, boards, 10.0 + OBJECT_GONE + 0.1) is boards  # it left the table


def test_a_lab_cameras_report_says_how_late_its_frames_went_out() -> None:
    stats = LabCameraStats(30.0, started=0.0)
    for n in range(30):
        stats.sent(n / 30.0, n / 30.0 + 0.05 + 0.002 * n)
    stats.dropped, stats.lost, stats.render_s = 1, 2, 0.31
    line = stats.summary(now=1.0)
    assert line.startswith('31.0 Hz of 30 Hz; 30 frames sent, 1 dropped, 0 without state')
    assert '2 exposures lost' in line
    assert 'render 10.0 ms' in line
    assert 'sent 79 ms after exposure (median)' in line
    assert stats.values()['delivered_ms'] == pytest.approx(79.0)
    slow = LabCameraStats(30.0, started=0.0)
    slow.frames = 20
    assert 'cannot keep up' in slow.summary(now=1.0)
