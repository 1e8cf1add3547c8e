"""The object's planar position predictor (paper Section III-B), manoeuvre-aware (pure core).

The paper predicts with one Kalman filter; its objects move on lines and parabolas. Objects in
a cell also stop, turn back and change speed, and a single constant-acceleration filter then
claims a certainty it does not have (round 1: the truth 2 s ahead inside its 3-sigma ellipse
65 % of the time on an object that stops). :class:`TargetPredictor` is an IMM over a stationary,
a constant-velocity and a constant-acceleration mode (:mod:`activesurv_prediction.imm`).

What a prediction at ``t`` reports:

* the mean: the modes' own extrapolations weighted by their probabilities now (what the object
  does if it keeps doing what it does); on the paper's lines and parabolas this is as accurate
  as the single filter;
* the covariance: the expected squared error of that mean over every way the mode may change
  before ``t`` (:func:`activesurv_prediction.imm.propagate_moments`). An object may stop, or
  start, within the next two seconds, and the ellipse says so.

Outliers: a fix whose innovation (against the mixture's predicted fix) has a squared
Mahalanobis distance above ``gate`` is rejected and does not touch the state; after
``max_rejections`` in a row the filter restarts at the newest fix with the velocity the rejected
fixes show (as the round-1 filter did).

The round-1 filter stays as
:class:`~activesurv_prediction.ca_predictor.ConstantAccelerationPredictor`
(``make_predictor('ca')``)
for comparison.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from activesurv_prediction import imm
from activesurv_prediction.base import (
    Array,
    OutlierGate,
    Predictor,
    UpdateResult,
    check_fix,
    check_positive,
    check_time,
)
from activesurv_prediction.ca_predictor import AxisFilter, ConstantAccelerationPredictor
from activesurv_prediction.errors import PredictionError

__all__ = ['PREDICTORS', 'TargetPredictor', 'UpdateResult', 'make_predictor']


class TargetPredictor:
    """IMM predictor of the top marker's (x, y) from overhead fixes.

    Args:
        measurement_std: std of one overhead fix, m (default 0.5 mm).
        modes: the motion modes and their switching (:class:`~activesurv_prediction.imm.ModeSet`).
        initial_velocity_std: prior std of the velocity at track start, m/s.
        initial_probabilities: mode probabilities (S, CV, CA) at track start.
        gate: chi-square (2 dof) threshold on the innovation; 0 disables gating.
        max_rejections: consecutive rejections after which the filter restarts.
        step: finest step (s) of a prediction; the mode may switch between steps
            (:func:`activesurv_prediction.imm.step_grid`).
    """

    def __init__(
        self,
        measurement_std: float = 0.5e-3,
        modes: imm.ModeSet | None = None,
        initial_velocity_std: float = 0.03,
        initial_probabilities: Sequence[float] = (0.2, 0.5, 0.3),
        gate: float = 50.0,
        max_rejections: int = 8,
        step: float = 0.5,
        reference_jerk_std: float = 7e-5,
        track_speed: float = 0.002,
    ) -> None:
        check_positive(
            measurement_std=measurement_std,
            initial_velocity_std=initial_velocity_std,
        )
        mu0 = np.asarray(initial_probabilities, dtype=np.float64).reshape(-1)
        if mu0.shape != (3,) or np.any(mu0 < 0.0) or not math.isclose(mu0.sum(), 1.0):
            raise PredictionError('initial_probabilities: three numbers >= 0 summing to 1')
        self.measurement_std = float(measurement_std)
        self.r = self.measurement_std**2
        self.modes = modes or imm.ModeSet()
        self.initial_velocity_std = float(initial_velocity_std)
        self.mu0 = mu0
        self.outliers = OutlierGate(gate, max_rejections)
        if not (math.isfinite(step) and 0.0 < step <= 2.0):
            raise PredictionError(f'step must be in (0, 2] s, got {step}')
        self.step = float(step)
        self.reference_jerk_std = float(reference_jerk_std)
        self.track_speed = float(track_speed)
        self.reference = AxisFilter(self.measurement_std, self.reference_jerk_std)
        self._reference_misses = 0
        self.states: imm.ModeStates | None = None
        self.last_time: float | None = None
        self.updates = 0
        self._steps: dict[float, tuple[Array, Array, Array, Array | None]] = {}
        self._grid = self.modes.grid(self.step)
        self._track_grid = (
            self.modes.grid(self.step, track=True) if self.modes.anisotropic else None
        )

    # -- state -------------------------------------------------------------------------------
    @property
    def rejections(self) -> int:
        """Fixes gated out as outliers so far."""
        return self.outliers.rejections

    @property
    def initialized(self) -> bool:
        return self.last_time is not None

    @property
    def mode_names(self) -> tuple[str, ...]:
        return imm.MODE_NAMES

    @property
    def mode_probabilities(self) -> Array:
        """Probabilities of S, CV, CA now (the initial ones before the first fix)."""
        return (self.mu0 if self.states is None else self.states.mu).copy()

    @property
    def state(self) -> Array:
        """The combined state mean (6,): ``[p_x, v_x, a_x, p_y, v_y, a_y]``."""
        if self.states is None:
            return np.zeros(6)
        return self.states.combined()[0]

    def reset(self) -> None:
        """Forget the track."""
        self.states = None
        self._reference_misses = 0
        self.last_time = None
        self.updates = 0
        self.outliers.clear()

    def _start(
        self, t: float, xy: Array, velocity: Array | None = None, velocity_std: float | None = None
    ) -> None:
        v = np.zeros(2) if velocity is None else velocity
        v_std = self.initial_velocity_std if velocity_std is None else velocity_std
        x = np.array([xy[0], v[0], 0.0, xy[1], v[1], 0.0])
        p1 = np.diag([self.r, v_std**2, self.modes.acceleration_std**2])
        P = np.zeros((6, 6))
        P[:3, :3] = P[3:, 3:] = p1
        xs = np.repeat(x[None, :], 3, axis=0)
        xs[imm.STATIONARY, [1, 2, 4, 5]] = 0.0
        Ps = np.repeat(P[None], 3, axis=0)
        for i in (1, 4):
            Ps[imm.STATIONARY, i, :] = Ps[imm.STATIONARY, :, i] = 0.0
            Ps[imm.STATIONARY, i, i] = self.modes.restart_speed_std**2
        self.states = imm.ModeStates(xs, Ps, self.mu0.copy())
        self.reference.start(t, xy, v, v_std, self.modes.acceleration_std)
        self._reference_misses = 0
        self.last_time = t
        self.outliers.clear()

    # -- filtering ---------------------------------------------------------------------------
    def update(self, t: float, xy: ArrayLike) -> UpdateResult:
        """Add an overhead fix ``xy`` (world, m) taken at ``t`` (s).

        Raises:
            ValueError: (a :class:`PredictionError`) for non-finite input or a time before the
                last update.
        """
        t = check_time(t)
        z = check_fix(xy)
        if self.states is None or self.last_time is None:
            self._start(t, z)
            self.updates = 1
            return UpdateResult(True, math.nan)
        if t < self.last_time:
            raise PredictionError(
                f'time {t:.6f} s is before the last update at {self.last_time:.6f} s; '
                'fixes must arrive in time order'
            )
        dt = t - self.last_time
        predicted = self.states
        if dt > 0.0:
            M, F, Q, Qt = self._step(dt)
            heading = self._heading(self.states)
            if heading is not None and Qt is not None:
                T = imm.track_rotation(heading)
                Q = T.T @ Qt @ T  # the track frame's noise, in the world frame
            predicted = imm.mix_and_predict(self.states, M, F, Q)
        self.states = predicted
        self.last_time = t
        updated, d2 = imm.update(predicted, z, self.r)
        verdict = self.outliers.judge(t, z, d2)
        if verdict == 'reject':
            return UpdateResult(False, d2)
        if verdict == 'restart':  # not an outlier but a manoeuvre: restart from the fixes
            self._start(t, z, *self.outliers.restart_velocity(self.measurement_std))
            self.updates += 1
            return UpdateResult(True, d2, restarted=True)
        was_stopped = predicted.mu[imm.STATIONARY] >= 0.5
        self.states = updated
        self._update_reference(t, z, was_stopped)
        self.updates += 1
        return UpdateResult(True, d2)

    def _update_reference(self, t: float, z: Array, was_stopped: bool) -> None:
        """Feed the moving object's reference filter; restart it from the IMM's moving modes
        when the object starts again or the reference no longer fits the fixes."""
        assert self.states is not None
        s = self.states
        moving = s.mu[imm.STATIONARY] < 0.5
        if moving and (was_stopped or self._reference_misses >= 3):
            w = s.mu[1:] / max(float(s.mu[1:].sum()), 1e-300)
            v = w @ s.x[1:, 1::3]
            self.reference.start(t, z, v, 0.003, self.modes.acceleration_std)
            self._reference_misses = 0
            return
        d2 = self.reference.update(t, z)
        self._reference_misses = self._reference_misses + 1 if d2 > 16.0 else 0

    def _heading(self, s: imm.ModeStates) -> float | None:
        """Direction of travel (rad) if the object moves (and the noise is anisotropic)."""
        if self._track_grid is None or s.mu[imm.STATIONARY] >= 0.5:
            return None
        v = self.reference.x[:, 1]
        if float(np.hypot(*v)) < self.track_speed:
            return None
        return math.atan2(float(v[1]), float(v[0]))

    def _step(self, dt: float) -> tuple[Array, Array, Array, Array | None]:
        """M, F, Q (world) and Q of the track frame of a filter step (cached: fixes come at
        a steady rate)."""
        key = round(dt, 9)
        hit = self._steps.get(key)
        if hit is None:
            F, Q = self.modes.models(dt)
            Qt = self.modes.models_batch(np.array([dt]), True)[1][0] if self._track_grid else None
            hit = (self.modes.transition(dt), F, Q, Qt)
            if len(self._steps) > 64:
                self._steps.clear()
            self._steps[key] = hit
        return hit

    # -- prediction --------------------------------------------------------------------------
    def _ready(self, times: Sequence[float]) -> tuple[imm.ModeStates, float, list[float]]:
        ts = [check_time(t) for t in times]
        if self.states is None or self.last_time is None:
            raise PredictionError('no fix yet: update() at least once before predicting')
        for t in ts:
            if t < self.last_time:
                raise PredictionError(
                    f'cannot predict at {t:.6f} s, before the last update at '
                    f'{self.last_time:.6f} s'
                )
        return self.states, self.last_time, ts

    def _means(self, s: imm.ModeStates, leads: Array) -> Array:
        """(K, 2): the likelier regime's extrapolation ``leads`` ahead: at rest if the
        stationary mode is likelier than not, else the reference filter's."""
        x = s.x[imm.STATIONARY]
        if s.mu[imm.STATIONARY] >= 0.5:
            out: Array = np.broadcast_to(x[::3], (len(leads), 2)).copy()
            return out
        return self.reference.extrapolate(leads)

    def predict_mean(self, t: float) -> Array:
        """The predicted (x, y) at ``t`` if every mode keeps on (cheap: no covariance)."""
        s, t0, (t,) = self._ready([t])
        out: Array = self._means(s, np.array([t - t0]))[0]
        return out

    def predict(self, t: float) -> tuple[Array, Array]:
        """Predicted (x, y) mean (2,) and its 2x2 covariance at ``t`` >= the last update."""
        return self.predict_many([t])[0]

    def predict_many(self, times: Sequence[float]) -> list[tuple[Array, Array]]:
        """:meth:`predict` at several instants in one sweep (the demand horizon).

        Raises:
            ValueError: before the first update, for a non-finite time or one before the last
                update.
        """
        s, t0, ts = self._ready(times)
        if not ts:
            return []
        leads = np.array(ts) - t0
        origin = s.mu @ s.x[:, ::3]
        means = self._means(s, leads) - origin
        heading = self._heading(s)
        grid = self._grid if heading is None or self._track_grid is None else self._track_grid
        moments = imm.propagate_moments(s, self.modes, leads, origin, grid, heading or 0.0)
        ezz, ez = moments[:, :2, :2], moments[:, :2, 2]
        mm = means[:, :, None] * means[:, None, :]
        cov = ezz - ez[:, :, None] * means[:, None, :] - means[:, :, None] * ez[:, None, :] + mm
        cov = 0.5 * (cov + cov.transpose(0, 2, 1))
        return [(means[i] + origin, cov[i]) for i in range(len(ts))]


def _ca(**kwargs: Any) -> Predictor:
    allowed = {'measurement_std', 'jerk_std', 'gate'}
    return ConstantAccelerationPredictor(**{k: v for k, v in kwargs.items() if k in allowed})


def _imm(**kwargs: Any) -> Predictor:
    allowed = {'measurement_std', 'gate'}
    return TargetPredictor(**{k: v for k, v in kwargs.items() if k in allowed})


PREDICTORS = {'imm': _imm, 'ca': _ca}


def make_predictor(kind: str = 'imm', **kwargs: Any) -> Predictor:
    """A predictor by name: ``imm`` (the default, :class:`TargetPredictor`) or ``ca`` (round 1).

    Raises:
        PredictionError: for an unknown kind.
    """
    if kind not in PREDICTORS:
        raise PredictionError(f'predictor must be one of {sorted(PREDICTORS)}, got {kind!r}')
    return PREDICTORS[kind](**kwargs)
