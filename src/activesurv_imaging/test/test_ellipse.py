"""Core tests of the weighted ellipse fit (no ROS)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_imaging.ellipse import Ellipse, ellipse_from_conic, fit_ellipse
from activesurv_imaging.errors import EllipseFitError


def _close(a: Ellipse, b: Ellipse, tol: float) -> None:
    assert np.allclose(a.center, b.center, atol=tol)
    assert np.allclose(a.semi_axes, b.semi_axes, atol=tol)
    d = abs(a.angle - b.angle) % math.pi
    assert min(d, math.pi - d) < tol / max(b.semi_axes[0] - b.semi_axes[1], 1e-9) + 1e-6


@settings(max_examples=150, deadline=None)
@given(
    st.floats(50, 600),
    st.floats(50, 400),
    st.floats(20, 250),
    st.floats(0.15, 1.0),
    st.floats(0, math.pi - 1e-6),
)
def test_exact_points_give_the_exact_ellipse(
    cx: float, cy: float, a: float, ratio: float, angle: float
) -> None:
    truth = Ellipse(np.array([cx, cy]), (a, a * ratio), angle)
    fit = fit_ellipse(truth.points(200))
    _close(fit, truth, 1e-6)
    assert fit.semi_axes[0] >= fit.semi_axes[1]
    assert 0.0 <= fit.angle < math.pi
    assert fit.rms_residual < 1e-6


def test_conic_round_trip_and_non_ellipse_conics() -> None:
    e = Ellipse(np.array([3.0, -2.0]), (5.0, 2.0), 0.3)
    _close(ellipse_from_conic(e.conic()), e, 1e-9)
    with pytest.raises(EllipseFitError, match='not an ellipse'):
        ellipse_from_conic([1, 0, -1, 0, 0, -1])  # hyperbola
    with pytest.raises(EllipseFitError):
        ellipse_from_conic([1, 0, 1, 0, 0, 1])  # imaginary


def test_weights_correct_the_density_bias_of_a_partial_dense_arc() -> None:
    # Points crowd on one side (as on a pixel chain). Unweighted algebraic fits are biased
    # there; the default (density + gradient) weights are not.
    truth = Ellipse(np.array([320.0, 240.0]), (110.0, 60.0), 0.4)
    rng = np.random.default_rng(0)
    t = np.concatenate(
        [np.linspace(0, 2 * np.pi, 120, endpoint=False), rng.uniform(0.0, 1.0, 600)]
    )
    a, b = truth.semi_axes
    ca, sa = math.cos(truth.angle), math.sin(truth.angle)
    x, y = a * np.cos(t), b * np.sin(t)
    pts = np.column_stack([320 + ca * x - sa * y, 240 + sa * x + ca * y])
    pts += rng.normal(0, 0.3, pts.shape)
    ours = fit_ellipse(pts)
    plain = fit_ellipse(pts, weights=np.ones(len(pts)))
    err_ours = np.linalg.norm(ours.center - truth.center)
    err_plain = np.linalg.norm(plain.center - truth.center)
    assert err_ours < 0.1
    assert err_ours < err_plain


def test_noisy_points_beat_or_match_opencv() -> None:
    truth = Ellipse(np.array([300.0, 200.0]), (120.0, 70.0), 1.1)
    rng = np.random.default_rng(5)
    errs_ours, errs_cv = [], []
    for _ in range(30):
        pts = truth.points(700) + rng.normal(0, 0.05, (700, 2))
        errs_ours.append(np.linalg.norm(fit_ellipse(pts).center - truth.center))
        (cx, cy), _, _ = cv2.fitEllipse(pts.astype(np.float32))
        errs_cv.append(np.hypot(cx - 300.0, cy - 200.0))
    assert np.median(errs_ours) <= np.median(errs_cv) + 1e-3


@pytest.mark.parametrize(
    ('points', 'match'),
    [
        (np.zeros((4, 2)), 'at least 5'),
        (np.zeros((10, 3)), r'\(N, 2\)'),
        (np.array([[np.nan, 0.0]] * 6), 'NaN'),
        (np.ones((8, 2)), 'coincide'),
        (np.column_stack([np.arange(10.0), np.arange(10.0)]), 'degenerate|no ellipse'),
    ],
)
def test_bad_points_raise(points: np.ndarray, match: str) -> None:
    with pytest.raises(EllipseFitError, match=match):
        fit_ellipse(points)


def test_bad_weights_raise() -> None:
    pts = Ellipse(np.array([0.0, 0.0]), (3.0, 2.0), 0.0).points(20)
    with pytest.raises(EllipseFitError, match='weights'):
        fit_ellipse(pts, weights=np.ones(3))
    with pytest.raises(EllipseFitError, match='non-zero'):
        fit_ellipse(pts, weights=np.r_[np.ones(3), np.zeros(17)])


def test_the_numpy_fallback_fits_as_the_compiled_fit_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """numba's ``eig`` raises where numpy's would return complex eigenvalues; the fit then
    solves with numpy, to the same ellipse (the path is forced here: no point set of 20 000
    random ones reached it)."""
    import activesurv_imaging.ellipse as ellipse_module

    rng = np.random.default_rng(4)
    t = rng.uniform(0.0, 2.0 * math.pi, 200)
    pts = np.column_stack([320 + 80 * np.cos(t), 240 + 45 * np.sin(t)]) + rng.normal(
        0, 0.2, (200, 2)
    )
    compiled = fit_ellipse(pts)

    def domain_change(*_: object) -> None:
        raise ValueError('eig() argument must not cause a domain change.')

    monkeypatch.setattr(ellipse_module, 'direct_fit', domain_change)
    monkeypatch.setattr(ellipse_module, 'reweighted_fit', domain_change)
    fallback = fit_ellipse(pts)
    assert np.allclose(fallback.center, compiled.center, atol=1e-6)
    assert np.allclose(fallback.semi_axes, compiled.semi_axes, atol=1e-6)
    assert fallback.angle == pytest.approx(compiled.angle, abs=1e-8)
