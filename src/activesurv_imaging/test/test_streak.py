"""Motion blur as a model (issue 33, item 2): the ellipse a marker had at mid-exposure, from
the streak its predicted velocity and the exposure time say it left."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.sensor_model import SensorModel
from activesurv_imaging.ellipse import Ellipse
from activesurv_imaging.marker_pose import MeasurementStatus, measure_marker
from activesurv_imaging.observation import image_streak, observe_marker
from activesurv_imaging.streak import _fit_shape, from_shape, shape_matrix, swept_contour, unswept
from activesurv_sim.frame_optics import FrameOptics
from activesurv_sim.optics import Optics, frame_optics
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise, look_at

CAM = replace(dynamic_camera('cam1'), exposure_time=0.01)


def test_shape_matrix_round_trip() -> None:
    e = Ellipse(np.array([10.0, 20.0]), (30.0, 22.0), 0.4)
    back = from_shape(e.center, shape_matrix(e))
    assert back.semi_axes == pytest.approx(e.semi_axes)
    assert back.angle == pytest.approx(e.angle)


@pytest.mark.parametrize('streak', [(18.0, 0.0), (0.0, 18.0), (30.0, 20.0)])
def test_unswept_inverts_the_sweep(streak: tuple[float, float]) -> None:
    e = Ellipse(np.array([100.0, 80.0]), (60.0, 45.0), 0.4)
    seen = from_shape(*_fit_shape(swept_contour(e, streak, 0.8, 256)))
    # The sweep narrows the ellipse across the motion; the centre stays at mid-exposure.
    assert np.allclose(seen.center, e.center, atol=0.01)
    assert abs(seen.semi_axes[1] - e.semi_axes[1]) + abs(seen.semi_axes[0] - e.semi_axes[0]) > 0.05
    back = unswept(seen, streak, 0.8)
    assert back.semi_axes == pytest.approx(e.semi_axes, abs=0.02)
    assert np.allclose(back.center, e.center, atol=0.01)


def test_short_or_absurd_streaks_are_left_alone() -> None:
    e = Ellipse(np.array([100.0, 80.0]), (60.0, 45.0), 0.4)
    assert unswept(e, (1.0, 1.0)) is e
    assert unswept(e, (1e4, 0.0)) is e
    assert unswept(e, (float('nan'), 0.0)) is e


def _frame(seed: int, speed: float) -> tuple[np.ndarray, object, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    T = look_at([0.05 + 0.15 * rng.uniform(), -0.55, 0.08], [0.0, 0.0, 0.05])
    p = np.array([0.0, 0.0, 0.05])
    ang = rng.uniform(0.0, np.pi)
    v = speed * np.array([np.cos(ang), 0.0, np.sin(ang)])
    o = Optics(f_number=4.0, focus_distance=0.5, exposure_time=0.01)
    lens = frame_optics(CAM, o, T, p, ((T, p - 0.005 * v), (T, p + 0.005 * v)))
    scene = Scene((Plate.disc(p, [0.0, -1.0, 0.0], 0.0125, 0.03),))
    return Renderer(CAM).render(T, scene, SensorNoise(), rng, lens), T, p, v


def test_a_streaked_marker_is_measured_where_it_was_at_mid_exposure() -> None:
    """17 px of streak (200 mm/s over 10 ms at 0.55 m): the predicted velocity (5 % off) and
    the exposure time take most of the error out (measured: 0.27 -> 0.05 mm median)."""
    plain, model = [], []
    for seed in range(6):
        img, T, p, v = _frame(seed, 0.2)
        normal = T.inverse().rotate([0.0, -1.0, 0.0])
        s = image_streak(CAM, T, p + 0.001, v * 1.05)
        assert s is not None
        assert 15.0 < float(np.hypot(*s)) < 19.0
        for streak, out in ((None, plain), (s, model)):
            m = measure_marker(img, CAM, 0.0125, normal, streak=streak)
            assert m.status is MeasurementStatus.OK, m.reason
            assert m.pose is not None
            out.append(float(np.linalg.norm(T.apply(m.pose.center) - p)))
    assert np.median(model) < 0.5 * np.median(plain), (plain, model)
    assert np.median(model) < 0.1e-3


def test_the_covariance_grows_with_the_streak_taken_out() -> None:
    img, T, p, v = _frame(1, 0.2)
    model = SensorModel.load(None)
    args = (img, CAM, T, 0.0125, model, 'cam1', 0, 0.0, [0.0, -1.0, 0.0])
    still = observe_marker(*args)
    moving = observe_marker(*args, streak=image_streak(CAM, T, p, v))
    assert still.covariance is not None
    assert moving.covariance is not None
    assert moving.streak is not None
    assert still.streak is None
    assert np.trace(moving.covariance) > np.trace(still.covariance)
    # Nothing to take out without a velocity or an exposure time.
    assert image_streak(CAM, T, p, None) is None
    assert image_streak(replace(CAM, exposure_time=0.0), T, p, v) is None


def test_the_imager_is_told_the_response_and_exposure_camera_info_lacks() -> None:
    from activesurv_imaging.capture import CaptureCore, ImagerConfig

    T = look_at([0.05, -0.5, 0.08], [0.0, 0.0, 0.05])
    bare = dynamic_camera('cam1')  # as a driver's camera_info has it: no response, no exposure
    told = ImagerConfig('cam1', gamma=2.2, exposure_time=0.008)
    core = CaptureCore(told, T, SensorModel.load(None), lambda g: g, bare)
    assert core.camera is not None
    assert (core.camera.gamma, core.camera.exposure_time) == (2.2, 0.008)
    core.set_camera(bare)  # a new camera_info: still what the imager was told
    assert (core.camera.gamma, core.camera.exposure_time) == (2.2, 0.008)
    plain = CaptureCore(ImagerConfig('cam1'), T, SensorModel.load(None), lambda g: g, CAM)
    assert plain.camera is CAM  # told nothing: the calibration's own
    with pytest.raises(Exception, match='gamma'):
        ImagerConfig('cam1', gamma=9.0)


def _streak_error(
    rng: np.random.Generator,
    renderer: Renderer,
    noise: SensorNoise,
    lengths: tuple[float, float],
    gammas: tuple[float, ...],
    defocus: float,
    told: float = 1.0,
) -> float:
    """One rendered view of a streaked marker 0.45-0.7 m away, a streak of ``lengths`` px (a
    range: drawn) in a random direction, a gamma of ``gammas`` (several: drawn), up to
    ``defocus`` px of defocus; measured told a streak ``told`` times the true one. Returns the
    centre error (m)."""
    marker, normal = np.zeros(3), np.array([0.0, -1.0, 0.0])
    eye = marker + [rng.uniform(-0.2, 0.2), -rng.uniform(0.45, 0.7), rng.uniform(-0.08, 0.08)]
    T = look_at(eye, marker + rng.normal(0.0, 0.003, 3))
    inv = T.inverse()
    a = rng.uniform(0.0, math.pi)
    length = lengths[0] if lengths[0] == lengths[1] else rng.uniform(*lengths)
    gamma = gammas[0] if len(gammas) == 1 else float(rng.choice(gammas))
    s = (length * math.cos(a), length * math.sin(a))
    optics = FrameOptics(defocus_sigma=rng.uniform(0.0, defocus), streak=s, gamma=gamma)
    scene = Scene((Plate.disc(marker, normal, 0.0125, 0.03),))
    img = renderer.render(T, scene, noise, rng, optics)
    m = measure_marker(
        img, CAM, 0.0125, inv.rotate(normal), gamma=gamma, streak=(told * s[0], told * s[1])
    )
    assert m.pose is not None, m.reason
    return float(np.linalg.norm(m.pose.center - inv.apply(marker)))


def test_a_long_streak_through_a_gamma_curve_in_a_noisy_frame() -> None:
    """25 px of streak, gamma 2.2, a quarter of the default's photo-electrons and twice its read
    noise, some defocus; the predicted streak 3 % long. On such a ramp noise pulled each first
    half-way crossing inwards (measured: 0.46 mm median, 0.85 mm p90 over 12 views); each edge
    measured again centred on it as its area edge, which the streak model predicts: 0.07 mm."""
    rng = np.random.default_rng(11)
    noise = SensorNoise(electrons_per_level=10.0, read_noise=2.0)
    renderer = Renderer(CAM)
    errors = [
        _streak_error(rng, renderer, noise, (25.0, 25.0), (2.2,), 1.5, told=1.03) for _ in range(8)
    ]
    assert np.median(errors) < 0.2e-3, errors


def test_edges_across_the_motion_are_measured_in_windows_of_their_own() -> None:
    """11-26 px streaks in any direction, the default sensor: every edge of a streaked marker
    measured in its own ramp's window (an edge across the motion is as short as a still one's)
    halves the error of windows as long as the longest ramp (measured over 80 such views: 0.044
    -> 0.022 mm median, p90 0.126 -> 0.062 mm; the photoreal motion case 0.27 -> 0.04 mm)."""
    rng = np.random.default_rng(5)
    noise = SensorNoise(electrons_per_level=40.0, read_noise=1.0)
    renderer = Renderer(CAM)
    errors = [
        _streak_error(rng, renderer, noise, (11.0, 26.0), (1.0, 1.6, 2.2), 0.6) for _ in range(24)
    ]
    # These 24 views: median 0.020 mm, p90 0.073 mm (0.028 / 0.128 mm with one window).
    assert np.median(errors) < 0.033e-3, np.round(np.array(errors) * 1e3, 3)
    assert np.percentile(errors, 90) < 0.09e-3, np.round(np.array(errors) * 1e3, 3)
