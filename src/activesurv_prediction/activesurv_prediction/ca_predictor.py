"""The round-1 predictor: one constant-acceleration Kalman filter (paper Section III-B).

Motion model: constant acceleration per axis, driven by piecewise-constant white jerk (filterpy)::

    x = [p_x, v_x, a_x, p_y, v_y, a_y]^T                         (6,)
    F(dt) = blkdiag(F1, F1),  F1 = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]     (6, 6)
    H = [[1, 0, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0]]                   (2, 6)
    Q(dt) = blkdiag(Q1, Q1),  Q1 = q g g^T, g = (dt^2/2, dt, 1)  (Q_discrete_white_noise)
    R = sigma_z^2 I                                                 (2, 2)

Why constant acceleration: the paper's paths are straight lines and parabolas. A parabola
driven at constant x-speed has constant y-acceleration, and at constant path speed an
acceleration that turns slowly. Constant velocity would miss ``a t^2 / 2`` (about 5-10 mm
two seconds ahead at 20 mm/s). The jerk noise ``q`` lets the acceleration follow curves,
stops and speed changes. Its default comes from the consistency benchmark (docs/performance.md,
"Prediction").

Outliers: a fix whose innovation has a squared Mahalanobis distance above ``gate``
(chi-square, 2 dof; 50 by default: a wrong detection is far out, while real fixes after a gap in
the frame stream can be several sigma off a constant-acceleration extrapolation) is rejected and
does not touch the state. After ``max_rejections``
rejections in a row the object has really manoeuvred: the filter restarts at the newest fix
with its velocity kept and the uncertainty inflated.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_prediction.base import (
    OutlierGate,
    UpdateResult,
    check_fix,
    check_positive,
    check_time,
)
from activesurv_prediction.errors import PredictionError

Array = NDArray[np.float64]

H = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 1.0, 0, 0]])


def transition(dt: float) -> Array:
    f = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    out = np.zeros((6, 6))
    out[:3, :3] = f
    out[3:, 3:] = f
    return out


def process_noise(dt: float, jerk_variance: float) -> Array:
    """Piecewise-constant white jerk: ``var * g g^T`` with ``g = (dt^2/2, dt, 1)``, the closed
    form of filterpy's ``Q_discrete_white_noise(dim=3)`` (written out: it is evaluated for every
    demand on every update)."""
    g = np.array([0.5 * dt * dt, dt, 1.0])
    q = jerk_variance * np.outer(g, g)
    out = np.zeros((6, 6))
    out[:3, :3] = q
    out[3:, 3:] = q
    return out


class ConstantAccelerationPredictor:
    """Kalman filter on overhead fixes of the top marker; predicts its (x, y) at any future time.

    Args:
        measurement_std: std of one overhead fix, m (default 0.5 mm).
        jerk_std: std of the white-noise jerk, m/s^3 (process noise).
        initial_velocity_std: prior std of the velocity at track start, m/s.
        initial_acceleration_std: prior std of the acceleration at track start, m/s^2.
        gate: chi-square (2 dof) threshold on the innovation; 0 disables gating.
        max_rejections: consecutive rejections after which the filter restarts.
    """

    def __init__(
        self,
        measurement_std: float = 0.5e-3,
        jerk_std: float = 2e-4,
        initial_velocity_std: float = 0.03,
        initial_acceleration_std: float = 0.01,
        gate: float = 50.0,
        max_rejections: int = 8,
    ) -> None:
        check_positive(
            measurement_std=measurement_std,
            jerk_std=jerk_std,
            initial_velocity_std=initial_velocity_std,
            initial_acceleration_std=initial_acceleration_std,
        )
        self.measurement_std = float(measurement_std)
        self.jerk_variance = float(jerk_std) ** 2
        self.initial_velocity_std = float(initial_velocity_std)
        self.initial_acceleration_std = float(initial_acceleration_std)
        self.outliers = OutlierGate(gate, max_rejections)
        # Deferred: filterpy's package imports scipy.stats (1 s of a process's start), and only
        # this optional filter (--predictor ca) needs it; the IMM default never builds one.
        from filterpy.kalman import KalmanFilter

        self.kf = KalmanFilter(dim_x=6, dim_z=2)
        self.kf.H = H.copy()
        self.kf.R = np.eye(2) * self.measurement_std**2
        self.last_time: float | None = None
        self.updates = 0

    @property
    def rejections(self) -> int:
        """Fixes gated out as outliers so far."""
        return self.outliers.rejections

    @property
    def initialized(self) -> bool:
        return self.last_time is not None

    @property
    def state(self) -> Array:
        return np.asarray(self.kf.x, dtype=np.float64).reshape(6).copy()

    def reset(self) -> None:
        """Forget the track."""
        self.last_time = None
        self.updates = 0
        self.outliers.clear()

    def _start(
        self, t: float, xy: Array, velocity: Array | None = None, velocity_std: float | None = None
    ) -> None:
        v = np.zeros(2) if velocity is None else velocity
        self.kf.x = np.array([xy[0], v[0], 0.0, xy[1], v[1], 0.0]).reshape(6, 1)
        v_std = self.initial_velocity_std if velocity_std is None else velocity_std
        p = np.diag([self.measurement_std**2, v_std**2, self.initial_acceleration_std**2])
        self.kf.P = np.zeros((6, 6))
        self.kf.P[:3, :3] = p
        self.kf.P[3:, 3:] = p
        self.last_time = t
        self.outliers.clear()

    def update(self, t: float, xy: ArrayLike) -> UpdateResult:
        """Add an overhead fix ``xy`` (world, m) taken at ``t`` (s).

        Raises:
            ValueError: (a :class:`PredictionError`) for non-finite input or a time before the
                last update.
        """
        t = check_time(t)
        z = check_fix(xy)
        if self.last_time is None:
            self._start(t, z)
            self.updates = 1
            return UpdateResult(True, math.nan)
        if t < self.last_time:
            raise PredictionError(
                f'time {t:.6f} s is before the last update at {self.last_time:.6f} s; '
                'fixes must arrive in time order'
            )
        dt = t - self.last_time
        if dt > 0.0:
            self.kf.F = transition(dt)
            self.kf.Q = process_noise(dt, self.jerk_variance)
            self.kf.predict()
        self.last_time = t
        innovation = z - (H @ self.kf.x).reshape(2)
        S = H @ self.kf.P @ H.T + self.kf.R
        d2 = float(innovation @ np.linalg.solve(S, innovation))
        verdict = self.outliers.judge(t, z, d2)
        if verdict == 'reject':
            return UpdateResult(False, d2)
        if verdict == 'restart':  # not an outlier but a manoeuvre: restart from the fixes
            self._start(t, z, *self.outliers.restart_velocity(self.measurement_std))
            self.updates += 1
            return UpdateResult(True, d2, restarted=True)
        self.kf.update(z)
        self.updates += 1
        return UpdateResult(True, d2)

    def predict_state(self, t: float) -> tuple[Array, Array]:
        """Full state mean (6,) and covariance (6, 6) at ``t`` (not stored).

        Raises:
            ValueError: before the first update, for a non-finite ``t`` or one before the last
                update.
        """
        t = check_time(t)
        if self.last_time is None:
            raise PredictionError('no fix yet: update() at least once before predicting')
        dt = float(t) - self.last_time
        if dt < 0.0:
            raise PredictionError(
                f'cannot predict at {float(t):.6f} s, before the last update at '
                f'{self.last_time:.6f} s'
            )
        x = np.asarray(self.kf.x, dtype=np.float64).reshape(6)
        P = np.asarray(self.kf.P, dtype=np.float64)
        if dt > 0.0:
            F = transition(dt)
            x = F @ x
            P = F @ P @ F.T + process_noise(dt, self.jerk_variance)
        return x, 0.5 * (P + P.T)

    def predict(self, t: float) -> tuple[Array, Array]:
        """Predicted (x, y) mean (2,) and its 2x2 covariance at ``t`` >= the last update."""
        x, P = self.predict_state(t)
        return H @ x, H @ P @ H.T

    def predict_mean(self, t: float) -> Array:
        return self.predict(t)[0]

    def predict_many(self, times: Sequence[float]) -> list[tuple[Array, Array]]:
        return [self.predict(t) for t in times]

    @property
    def mode_names(self) -> tuple[str, ...]:
        return ('constant_acceleration',)

    @property
    def mode_probabilities(self) -> Array:
        return np.ones(1)


class AxisFilter:
    """The same constant-acceleration model, both axes at once as (2, 3) states and (2, 3, 3)
    covariances (the axes are independent: F, Q, R are block diagonal). Written out with numpy
    because it runs beside the IMM on every fix; :class:`ConstantAccelerationPredictor` is the
    filterpy reference the tests compare it with.
    """

    def __init__(self, measurement_std: float, jerk_std: float) -> None:
        check_positive(measurement_std=measurement_std, jerk_std=jerk_std)
        self.r = float(measurement_std) ** 2
        self.jerk_variance = float(jerk_std) ** 2
        self.x = np.zeros((2, 3))
        self.P = np.zeros((2, 3, 3))
        self.last_time: float | None = None

    def start(
        self, t: float, xy: Array, velocity: Array, velocity_std: float, a_std: float
    ) -> None:
        self.x = np.column_stack([xy, velocity, np.zeros(2)])
        self.P = np.broadcast_to(np.diag([self.r, velocity_std**2, a_std**2]), (2, 3, 3)).copy()
        self.last_time = t

    def update(self, t: float, z: Array) -> float:
        """Predict to ``t`` and update with ``z`` (2,); returns the innovation's squared
        Mahalanobis distance."""
        assert self.last_time is not None
        dt = t - self.last_time
        if dt > 0.0:
            f = transition(dt)[:3, :3]
            g = np.array([0.5 * dt * dt, dt, 1.0])
            self.x = self.x @ f.T
            self.P = f @ self.P @ f.T + self.jerk_variance * np.outer(g, g)
            self.last_time = t
        y = z - self.x[:, 0]
        s = self.P[:, 0, 0] + self.r
        k = self.P[:, :, 0] / s[:, None]
        self.x = self.x + k * y[:, None]
        self.P = self.P - k[:, :, None] * self.P[:, None, 0, :]
        return float(np.sum(y * y / s))

    def extrapolate(self, leads: Array) -> Array:
        """(K, 2) positions ``leads`` (K,) seconds after the last fix."""
        x = self.x
        out: Array = x[:, 0] + leads[:, None] * x[:, 1] + 0.5 * (leads * leads)[:, None] * x[:, 2]
        return out
