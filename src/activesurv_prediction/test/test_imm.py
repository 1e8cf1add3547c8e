"""The IMM predictor: filtering against filterpy's IMMEstimator, switching-aware prediction
against a Monte Carlo simulation of the same jump system, honesty on manoeuvres (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import IMMEstimator, KalmanFilter

from activesurv_prediction import imm
from activesurv_prediction.ca_predictor import AxisFilter, ConstantAccelerationPredictor
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.manoeuvre import ManoeuvreDetector
from activesurv_prediction.predictor import TargetPredictor, make_predictor

DT = 1.0 / 30.0
R = 0.5e-3**2


def _stop_and_go(t: float) -> np.ndarray:
    s = 0.018 * min(t, 4.0) + 0.018 * max(t - 7.0, 0.0)  # stops for 3 s
    return np.array([0.1 + s, 0.1 + 0.3 * s])


def test_imm_filtering_matches_filterpy_imm_estimator() -> None:
    modes = imm.ModeSet()
    F, Q = modes.models(DT)
    M = modes.transition(DT)
    x0 = np.array([0.1, 0.01, 0.0, 0.1, 0.0, 0.0])
    P0 = np.diag([R, 1e-4, 1e-4, R, 1e-4, 1e-4])
    mu0 = np.array([0.2, 0.5, 0.3])
    filters = []
    for j in range(3):
        kf = KalmanFilter(dim_x=6, dim_z=2)
        kf.x, kf.P, kf.F, kf.Q = x0.reshape(6, 1).copy(), P0.copy(), F[j], Q[j]
        kf.H = np.zeros((2, 6))
        kf.H[0, 0] = kf.H[1, 3] = 1.0
        kf.R = np.eye(2) * R
        filters.append(kf)
    ref = IMMEstimator(filters, mu0.copy(), M)
    ours = imm.ModeStates(np.repeat(x0[None], 3, 0), np.repeat(P0[None], 3, 0), mu0.copy())
    rng = np.random.default_rng(1)
    for k in range(1, 150):
        z = _stop_and_go(k * DT) + rng.normal(0.0, 0.5e-3, 2)
        ref.predict()
        ref.update(z)
        ours, _ = imm.update(imm.mix_and_predict(ours, M, F, Q), z, R)
        assert np.allclose(ours.mu, ref.mu, rtol=1e-6, atol=1e-9), k
        for j in range(3):
            assert np.allclose(ours.x[j], filters[j].x.reshape(6), rtol=1e-7, atol=1e-10)
            assert np.allclose(ours.P[j], filters[j].P, rtol=1e-6, atol=1e-14)
    assert ours.mu[imm.STATIONARY] > 0.9  # 5 s: the object stopped at 4 s


@pytest.mark.parametrize('heading', [None, 0.7])
def test_switching_moments_match_a_monte_carlo_of_the_jump_system(heading: float | None) -> None:
    """In the world frame, and in the track frame (anisotropic noise, the object heading
    ``heading`` rad): the simulation then draws the track frame's noise turned into the world."""
    modes = imm.ModeSet()
    rng = np.random.default_rng(2)
    x = np.array(
        [
            [0.2, 0.0, 0.0, 0.1, 0.0, 0.0],
            [0.2, 0.02, 0.0, 0.1, 0.01, 0.0],
            [0.2, 0.02, 0.004, 0.1, 0.01, -0.002],
        ]
    )
    P = np.repeat(np.diag([R, 4e-6, 1e-6, R, 4e-6, 1e-6])[None], 3, 0)
    s = imm.ModeStates(x, P, np.array([0.1, 0.6, 0.3]))
    lead, steps, n = 2.0, 4, 40000
    grid = imm.MomentGrid(modes, lead / steps, track=heading is not None)
    moments = imm.propagate_moments(s, modes, np.array([lead]), np.zeros(2), grid, heading or 0.0)[
        0
    ]
    mean, second = moments[:2, 2], moments[:2, :2]
    cov = second - np.outer(mean, mean)
    # Simulate: mode chain with M(dt) at each step boundary, then that mode's linear model.
    dt = lead / steps
    F, Q = modes.models(dt)
    if heading is not None:
        T = imm.track_rotation(heading)
        Q = T.T @ modes.models_batch(np.array([dt]), track=True)[1][0] @ T
        assert not np.allclose(Q[1], modes.models(dt)[1][1])  # really anisotropic
    M = modes.transition(dt)
    mode = rng.choice(3, size=n, p=s.mu)
    states = np.array([rng.multivariate_normal(x[m], P[m]) for m in mode])
    cq = [np.linalg.cholesky(Q[j] + 1e-30 * np.eye(6)) for j in range(3)]
    for _ in range(steps):
        u = rng.random(n)
        mode = (u[:, None] > np.cumsum(M[mode], axis=1)).sum(axis=1)
        noise = rng.standard_normal((n, 6))
        for j in range(3):
            sel = mode == j
            states[sel] = states[sel] @ F[j].T + noise[sel] @ cq[j].T
    z = states[:, ::3]
    assert np.allclose(z.mean(axis=0), mean, atol=4 * math.sqrt(cov.max() / n) + 1e-6)
    sim = np.cov(z.T)
    assert np.allclose(sim, cov, rtol=0.05, atol=1e-8)


def test_axis_filter_is_the_filterpy_constant_acceleration_filter() -> None:
    ref = ConstantAccelerationPredictor(measurement_std=0.5e-3, jerk_std=2e-4, gate=0.0)
    ours = AxisFilter(0.5e-3, 2e-4)
    rng = np.random.default_rng(3)
    for k in range(200):
        t = k * DT
        z = _stop_and_go(t) + rng.normal(0.0, 0.5e-3, 2)
        ref.update(t, z)
        if k == 0:
            ours.start(t, z, np.zeros(2), ref.initial_velocity_std, ref.initial_acceleration_std)
        else:
            ours.update(t, z)
    assert np.allclose(ours.x.reshape(-1), ref.state.reshape(2, 3).reshape(-1), atol=1e-10)
    assert np.allclose(ours.extrapolate(np.array([2.0]))[0], ref.predict(ours.last_time + 2.0)[0])


def _coverage(kind: str, lead: float = 2.0) -> tuple[float, float]:
    rng = np.random.default_rng(4)
    inside = {'imm': [], 'ca': []}
    for _ in range(3):
        preds = {k: make_predictor(k) for k in inside}
        for k in range(int(14.0 / DT)):
            t = k * DT
            z = _stop_and_go(t) + rng.normal(0.0, 0.5e-3, 2)
            for name, p in preds.items():
                p.update(t, z)
                if t >= 2.0 and k % 3 == 0:
                    m, c = p.predict(t + lead)
                    e = m - _stop_and_go(t + lead)
                    inside[name].append(float(e @ np.linalg.solve(c, e)) <= 9.0)
    return float(np.mean(inside['imm'])), float(np.mean(inside['ca']))


def test_the_imm_ellipse_holds_the_truth_of_an_object_that_stops() -> None:
    imm_inside, ca_inside = _coverage('stop')
    assert ca_inside < 0.85  # round 1: the constant-acceleration filter claims too much
    assert imm_inside >= 0.95


def test_a_horizon_in_one_sweep_equals_point_by_point() -> None:
    p = TargetPredictor()
    for k in range(90):
        p.update(k * DT, _stop_and_go(k * DT))
    t0 = p.last_time
    assert t0 is not None
    times = [t0 + 3.0, t0 + 0.5, t0 + 1.5]
    many = p.predict_many(times)
    for t, (m, c) in zip(times, many, strict=True):
        m1, c1 = p.predict(t)
        assert np.allclose(m, m1)
        assert np.allclose(c, c1)
        assert np.allclose(p.predict_mean(t), m)
        assert np.all(np.linalg.eigvalsh(c) > 0.0)
    assert many[0][1][0, 0] > many[2][1][0, 0] > many[1][1][0, 0]  # further: less certain


def test_manoeuvres_of_a_stop_and_go_object() -> None:
    p = TargetPredictor()
    det = ManoeuvreDetector()
    events = []
    rng = np.random.default_rng(5)
    for k in range(int(12.0 / DT)):
        t = k * DT
        r = p.update(t, _stop_and_go(t) + rng.normal(0.0, 0.5e-3, 2))
        if det.update(p.mode_probabilities, r.restarted):
            events.append((round(t, 1), det.regime))
    stops = [t for t, regime in events if regime == 'stopped']
    starts = [t for t, regime in events if regime != 'stopped' and t > 4.0]
    assert stops
    assert 4.0 < stops[0] < 5.0
    assert starts
    assert 7.0 < starts[0] < 8.5
    assert det.count == len(events)


def test_bad_input_and_names() -> None:
    with pytest.raises(PredictionError, match='predictor must be one of'):
        make_predictor('kalman')
    with pytest.raises(PredictionError, match='generator'):
        imm.ModeSet(rates=np.ones((3, 3)))
    with pytest.raises(PredictionError, match='jerk_psd'):
        imm.ModeSet(jerk_psd=-1.0)
    with pytest.raises(PredictionError, match='initial_probabilities'):
        TargetPredictor(initial_probabilities=(0.5, 0.5, 0.5))
    with pytest.raises(ValueError, match='finite'):
        TargetPredictor().update(0.0, (math.nan, 0.1))
    with pytest.raises(PredictionError, match='threshold'):
        ManoeuvreDetector(enter=0.3)
    assert TargetPredictor().mode_names == imm.MODE_NAMES
    assert make_predictor('ca').mode_names == ('constant_acceleration',)
