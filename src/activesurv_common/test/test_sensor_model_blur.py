"""The sensor model's third factor (issue 33, item 4): a blurred view (depth of field, motion)
is measured less well, by a factor the blur study measured; the lens settings that predict
the depth of field's blur travel with the calibration."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from activesurv_common.camera_model import CameraModel, dynamic_camera, thin_lens_sigma
from activesurv_common.errors import CalibrationError, SensorModelError
from activesurv_common.sensor_model import SensorModel, blur_term, image_blur


def test_the_shipped_model_weighs_blur() -> None:
    m = SensorModel.load(None)
    assert m.models_blur
    assert np.all((m.blur_coefficients > 0.3) & (m.blur_coefficients < 2.0))
    assert 0.5 < m.blur_base < 1.5  # the lens's and pixel's own blur, px
    d, theta = 0.6, math.radians(30.0)
    sharp = m.variances(d, theta)
    assert np.array_equal(m.variances(d, theta, 0.0), sharp)  # no blur: as it always was
    blurred = m.variances(d, theta, 4.0)
    assert np.allclose(blurred, sharp * (1.0 + 16.0) ** m.blur_coefficients)
    batch = m.variances_batch([d, d], [theta, theta], [0.0, 4.0])
    assert np.allclose(batch, [sharp, blurred])
    # Beyond MAX_BLUR the factor stops growing.
    assert np.array_equal(m.variances(d, theta, 12.0), m.variances(d, theta, 50.0))


def test_a_model_without_blur_coefficients_loads_and_says_what_it_said(tmp_path: Path) -> None:
    m = SensorModel.load(None)
    plain = replace(m, blur_coefficients=np.zeros(6), blur_base=0.0)
    path = tmp_path / 'plain.yaml'
    plain.save(path)
    assert 'blur_coefficients' not in path.read_text()
    back = SensorModel.load(path)
    assert not back.models_blur
    assert np.array_equal(
        back.variances_batch([0.6], [0.5], [8.0]), back.variances_batch([0.6], [0.5])
    )
    path = tmp_path / 'blur.yaml'
    m.save(path)
    again = SensorModel.load(path)
    assert np.allclose(again.blur_coefficients, m.blur_coefficients)
    assert again.blur_base == pytest.approx(m.blur_base)
    with pytest.raises(SensorModelError, match='blur_coefficients'):
        replace(m, blur_coefficients=np.full(6, -1.0))


def test_blur_of_a_view_is_its_edges_beyond_a_sharp_one_and_its_streak() -> None:
    m = SensorModel.load(None)
    assert m.blur_of(m.blur_base) == pytest.approx(0.0)
    assert m.blur_of(math.hypot(m.blur_base, 3.0)) == pytest.approx(3.0)
    assert m.blur_of(m.blur_base, 12.0) == pytest.approx(12.0 / math.sqrt(12.0))
    assert image_blur(3.0, 0.0) == pytest.approx(3.0)
    assert blur_term(float('nan')) == pytest.approx(0.0)


def test_lens_settings_round_trip_and_predict_the_depth_of_field(tmp_path: Path) -> None:
    cam = replace(dynamic_camera(), f_number=4.0, focus_distance=0.6, focal_length=0.025)
    path = tmp_path / 'cam.yaml'
    cam.save(path)
    back = CameraModel.load(path)
    assert (back.f_number, back.focus_distance, back.focal_length) == (4.0, 0.6, 0.025)
    sigma = back.defocus_sigma([0.6, 0.5, 0.8])
    assert sigma[0] == pytest.approx(0.0)
    assert 0.5 < sigma[1] < sigma[2]
    assert sigma[1] == pytest.approx(float(thin_lens_sigma(cam.fx, 0.025, 4.0, 0.6, 0.5)))
    assert np.all(dynamic_camera().defocus_sigma([0.5, 0.8]) == 0.0)  # no lens: unknown
    with pytest.raises(CalibrationError, match='lens'):
        replace(dynamic_camera(), f_number=4.0)  # one of three
