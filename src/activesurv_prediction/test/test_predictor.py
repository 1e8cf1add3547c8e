"""Core tests of the Kalman predictor, tracker and demand horizon (no ROS)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from activesurv_prediction.demands import (
    DemandSchedule,
    TargetGeometry,
    predict_demands,
)
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.predictor import TargetPredictor
from activesurv_prediction.tracker import Tracker, TrackState, Workspace

Path2 = Callable[[float], np.ndarray]


def line(t: float) -> np.ndarray:
    return np.array([0.1 + 0.016 * t, 0.05 + 0.012 * t])


def parabola(t: float, v: float = 0.02) -> np.ndarray:
    """y = 0.08 + 6 (x - 0.25)^2 at constant path speed v (numerically by arc length)."""
    xs = np.linspace(0.15, 0.45, 3001)
    ys = 0.08 + 6.0 * (xs - 0.25) ** 2
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xs), np.diff(ys)))])
    return np.array([np.interp(v * t, s, xs), np.interp(v * t, s, ys)])


def arc(t: float) -> np.ndarray:
    w = 0.02 / 0.08  # 20 mm/s on an 80 mm radius circle
    return np.array([0.25 + 0.08 * math.cos(w * t), 0.1 + 0.08 * math.sin(w * t)])


def stop_and_go(t: float) -> np.ndarray:
    s = 0.018 * min(t, 4.0) + 0.018 * max(t - 6.0, 0.0)  # stops for 2 s
    return np.array([0.1 + s, 0.1])


def speed_change(t: float) -> np.ndarray:
    s = 0.008 * t if t < 5 else 0.04 + 0.02 * (t - 5)
    return np.array([0.05 + s, 0.1 + 0.3 * s])


def _run(path: Path2, seconds: float = 12.0, seed: int = 0) -> tuple[list[float], list[float]]:
    rng = np.random.default_rng(seed)
    p = TargetPredictor()
    errs, d2 = [], []
    for k in range(int(seconds * 30)):
        t = k / 30.0
        p.update(t, path(t) + rng.normal(0.0, 0.5e-3, 2))
        if t >= 2.0 and t + 2.0 <= seconds:
            m, c = p.predict(t + 2.0)
            e = m - path(t + 2.0)
            errs.append(float(np.linalg.norm(e)))
            d2.append(float(e @ np.linalg.solve(c, e)))
    return errs, d2


@pytest.mark.parametrize(('path', 'rms_limit'), [(line, 3e-3), (parabola, 6e-3), (arc, 8e-3)])
def test_two_second_predictions_on_smooth_paths(path: Path2, rms_limit: float) -> None:
    errs, d2 = _run(path)
    assert math.sqrt(np.mean(np.square(errs))) < rms_limit
    assert np.mean(np.array(d2) <= 9.0) >= 0.95  # 3-sigma ellipse holds the truth


@pytest.mark.parametrize('path', [stop_and_go, speed_change])
def test_stops_and_speed_changes_are_followed(path: Path2) -> None:
    rng = np.random.default_rng(3)
    p = TargetPredictor()
    for k in range(12 * 30):
        t = k / 30.0
        p.update(t, path(t) + rng.normal(0.0, 0.5e-3, 2))
    # Some time after the manoeuvre, short-term predictions are good again.
    m, _ = p.predict(12.0 + 0.5)
    assert np.linalg.norm(m - path(12.5)) < 3e-3


def test_a_wrong_detection_does_not_drag_the_track() -> None:
    rng = np.random.default_rng(4)
    p = TargetPredictor()
    for k in range(150):
        t = k / 30.0
        z = line(t) + rng.normal(0.0, 0.5e-3, 2)
        if k == 100:
            z = z + [0.05, -0.03]  # the overhead detector latched on to something else
            r = p.update(t, z)
            assert not r.accepted
            assert r.mahalanobis2 > 100
            continue
        assert p.update(t, z).accepted
    assert p.rejections == 1
    m, _ = p.predict(5.0)
    assert np.linalg.norm(m - line(5.0)) < 2e-3


def test_contract() -> None:
    p = TargetPredictor(measurement_std=1e-3)
    assert p.r == pytest.approx(1e-6)
    with pytest.raises(ValueError, match='no fix yet'):
        p.predict(1.0)
    p.update(1.0, (0.1, 0.2))
    mean, cov = p.predict(1.0)
    assert mean.shape == (2,)
    assert cov.shape == (2, 2)
    assert np.allclose(mean, [0.1, 0.2])
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    with pytest.raises(ValueError, match='before the last update'):
        p.predict(0.5)
    with pytest.raises(ValueError, match='before the last update'):
        p.update(0.9, (0.1, 0.2))
    with pytest.raises(ValueError, match='finite'):
        p.update(2.0, (float('nan'), 0.2))
    with pytest.raises(ValueError, match='finite'):
        p.update(float('inf'), (0.1, 0.2))
    with pytest.raises(ValueError, match='finite'):
        p.predict(float('nan'))
    with pytest.raises(ValueError, match='measurement_std'):
        TargetPredictor(measurement_std=-1.0)


def test_tracker_life_cycle() -> None:
    tr = Tracker(confirm_fixes=5, lost_timeout=0.5)
    assert tr.update(0.0, (-0.2, 0.1)) is None  # not in the workspace yet
    assert tr.state is TrackState.NONE
    for k in range(5):
        tr.update(0.1 * k + 0.1, (0.01 + 0.002 * k, 0.1))
    assert tr.state is TrackState.CONFIRMED
    assert not tr.check_timeout(0.8)
    assert tr.check_timeout(1.2)
    assert tr.state is TrackState.LOST
    tr.update(2.0, (0.2, 0.1))
    assert tr.state is TrackState.TENTATIVE
    assert tr.tracks_started == 2
    tr.update(2.1, (0.6, 0.1))  # left the table
    assert tr.state is TrackState.LOST
    with pytest.raises(PredictionError):
        Workspace(0.5, 0.0, 0.0, 0.2)


def test_demand_schedule_and_horizon() -> None:
    s = DemandSchedule.regular(4.0, 2.0, 10)
    assert s.times[-1] == pytest.approx(22.0)
    assert s.upcoming(5.0, 3) == [(1, 6.0), (2, 8.0), (3, 10.0)]
    assert s.upcoming(100.0, 3) == []
    with pytest.raises(PredictionError, match='increasing'):
        DemandSchedule.explicit([1.0, 1.0])
    with pytest.raises(PredictionError):
        DemandSchedule.regular(0.0, -1.0, 3)
    p = TargetPredictor()
    for k in range(60):
        p.update(k / 30.0, line(k / 30.0))
    geo = TargetGeometry.create([0.0, -0.03, -0.03], [0.0, -2.0, 0.0])
    preds = predict_demands(p, s, geo, top_height=0.08, now=5.0, m=4)
    assert [d.index for d in preds] == [1, 2, 3, 4]
    d = preds[0]
    expected = np.r_[line(6.0), 0.08] + [0.0, -0.03, -0.03]
    assert np.linalg.norm(d.position - expected) < 2e-3
    assert np.allclose(d.normal, [0.0, -1.0, 0.0])
    assert d.covariance.shape == (6, 6)
    # Further demands are less certain.
    assert preds[-1].covariance[0, 0] > preds[0].covariance[0, 0]


@pytest.mark.parametrize('dt', [0.001, 1.0 / 30.0, 0.5, 2.0])
def test_process_noise_matches_filterpy(dt: float) -> None:
    from filterpy.common import Q_discrete_white_noise

    from activesurv_prediction.ca_predictor import process_noise

    q = process_noise(dt, 4e-8)
    assert np.allclose(q[:3, :3], Q_discrete_white_noise(dim=3, dt=dt, var=4e-8), rtol=1e-12)
    assert np.allclose(q[3:, 3:], q[:3, :3])
