"""The sensor model's blur factor is fitted from the blur study's cells (issue 33, item 4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from activesurv_common.errors import SensorModelError
from activesurv_common.sensor_model import SensorModel
from activesurv_studies.sensor_model_experiment import CellResult, _cell, fit_blur


def _cells(cb: np.ndarray, base: float = 0.9) -> list[CellResult]:
    out = []
    for d, t in ((0.5, 0.3), (0.7, 0.9)):
        sharp = np.full(6, 1e-8) * (1.0 + d)
        out.append(CellResult(d, t, sharp, 20, 0, 0.0, base))
        for b in (2.0, 4.0, 8.0):
            var = sharp * (1.0 + b * b) ** cb
            out.append(CellResult(d, t, var, 20, 0, b, math.hypot(base, b)))
    return out


def test_the_blur_factor_is_recovered_from_the_cells() -> None:
    cb = np.array([0.9, 0.8, 0.7, 1.0, 0.6, 0.5])
    m = fit_blur(SensorModel.load(None), _cells(cb))
    assert np.allclose(m.blur_coefficients, cb, atol=1e-9)
    assert m.blur_base == pytest.approx(0.9)
    assert 'blur_study' in m.samples
    with pytest.raises(SensorModelError, match='no blurred cell'):
        fit_blur(SensorModel.load(None), [c for c in _cells(cb) if c.blur == 0.0])


def test_a_blurred_cell_is_measured_worse_than_its_sharp_twin() -> None:
    from activesurv_common.camera_model import dynamic_camera
    from activesurv_sim.render import SensorNoise

    args = (0.6, 0.5, 6, 11, 0.0125, dynamic_camera(), SensorNoise())
    sharp = _cell(args)
    blurred = _cell((*args, 6.0))
    assert sharp.successes == blurred.successes == 6
    assert blurred.edge_blur > sharp.edge_blur + 4.0
    assert np.sum(blurred.variances[:3]) > np.sum(sharp.variances[:3])
