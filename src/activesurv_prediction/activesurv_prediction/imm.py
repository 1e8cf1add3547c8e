"""Interacting multiple model (IMM) filtering and switching-aware prediction (pure core).

Three motion modes share one state per axis, ``x = [p_x, v_x, a_x, p_y, v_y, a_y]^T`` (6,);
each mode uses the part it needs and sets the rest to a prior (padding, as an IMM needs)::

    stationary (S):   F1 = [[1, 0, 0], [0, 0, 0], [0, 0, 0]]
                      Q1 = diag(q_s dt, sigma_r^2, sigma_a^2)
    constant velocity (CV):
                      F1 = [[1, dt, 0], [0, 1, 0], [0, 0, 0]]
                      Q1 = q_a [[dt^3/3, dt^2/2, 0], [dt^2/2, dt, 0], [0, 0, 0]]
                           + diag(0, 0, sigma_a^2)
    constant acceleration (CA):
                      F1 = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]
                      Q1 = q_j [[dt^5/20, dt^4/8, dt^3/6], [dt^4/8, dt^3/3, dt^2/2],
                                [dt^3/6, dt^2/2, dt]]
    F = blkdiag(F1, F1) (6, 6),  Q = blkdiag(Q1, Q1) (6, 6),
    H = [[1, 0, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0]] (2, 6),  R = sigma_z^2 I (2, 2)

The noise is continuous-time (white acceleration for CV, white jerk for CA, Van Loan's closed
forms), so steps of any length compose: a prediction over 2 s in one step or in eight agrees.
The padded components are *priors*, not states: a stationary object's ``v`` is the velocity it
would start with (``sigma_r``), a CV object's ``a`` the acceleration it would take up
(``sigma_a``). When the IMM mixes a mode into another, the new mode inherits that prior: an
object that starts from rest starts with an honestly unknown velocity.

Manoeuvres are mostly along the track: objects stop, turn back and change speed along their
path, and turn at the few mm/s^2 of a bend. So the acceleration a CV object would take up is
anisotropic: ``sigma_a`` along the direction of travel, ``lateral_acceleration_std`` across
it (likewise the CV and CA noise, if lateral values are given). While the object moves, the
filter's Q is that of the *track frame* (first axis along the reference velocity) turned into
the world frame, and predictions run in the track frame (:class:`MomentGrid` with ``track``);
an object at rest may start in any direction and gets the along-track values on both axes.
Before, the 15 mm/s^2 sideways a CV object might take up made a line's ellipse 9 mm wide 2 s
ahead for a 1 mm error.

Mode switching is a continuous-time Markov chain with generator ``rates`` (1/s), so the
transition matrix of a step is ``M(dt) = expm(rates * dt)`` whatever the fix rate.

Filtering is the textbook IMM (Bar-Shalom, Li & Kirubarajan, ch. 11.6): mixing, mode-matched
Kalman prediction and update, mode probabilities from the likelihoods. It is written here with
the three modes stacked in arrays because filterpy's ``IMMEstimator`` (the reference the tests
compare it with, step by step) loops over Python filter objects and takes 0.8 ms a fix on this
machine, and keeps one transition matrix for every step.

Prediction ahead (:func:`propagate_moments`) is exact in mean and covariance for the switching
system (a Markov jump linear system): per mode it carries the probability-weighted first and
second moments ``A_j = E[[x; 1][x; 1]^T 1{mode = j}]`` (7, 7) through
``A_j' = G_j (sum_i M_ij A_i) G_j^T + (sum_i M_ij q_i) Qa_j`` with ``G_j = blkdiag(F_j, 1)``,
switching at the sub-step boundaries. The mode may change before the instant predicted, and the
covariance says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from activesurv_prediction.errors import PredictionError

Array = NDArray[np.float64]

MODE_NAMES = ('stationary', 'constant_velocity', 'constant_acceleration')
STATIONARY, CONSTANT_VELOCITY, CONSTANT_ACCELERATION = 0, 1, 2
POS = np.array([0, 3])  # indices of p_x, p_y in the state


@dataclass(frozen=True)
class ModeSet:
    """The three motion modes and how they switch.

    Attributes:
        rates: (3, 3) generator of the mode chain, 1/s (rows: from S, CV, CA; rows sum to 0).
        stationary_psd: q_s, position random walk of a stationary object, m^2/s.
        restart_speed_std: sigma_r, speed per axis an object at rest starts with, m/s.
        acceleration_psd: q_a, white acceleration of CV, m^2/s^3.
        acceleration_std: sigma_a, acceleration per axis taken up when CA starts, m/s^2.
        jerk_psd: q_j, white jerk of CA, m^2/s^5.
        lateral_acceleration_std, lateral_acceleration_psd, lateral_jerk_psd: the same across
            the direction of travel (None: as along it).
    """

    rates: Array = field(
        default_factory=lambda: generator([[0.0, 0.25, 0.05], [0.04, 0.0, 0.15], [0.04, 0.3, 0.0]])
    )
    stationary_psd: float = (0.05e-3) ** 2
    restart_speed_std: float = 0.012
    acceleration_psd: float = 1e-6
    acceleration_std: float = 0.015
    jerk_psd: float = 1.2e-6
    lateral_acceleration_std: float | None = 0.002
    lateral_acceleration_psd: float | None = None
    lateral_jerk_psd: float | None = None

    def __post_init__(self) -> None:
        r = np.asarray(self.rates, dtype=np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise PredictionError('mode rates must be a finite 3x3 matrix')
        off = r - np.diag(np.diag(r))
        if np.any(off < 0.0) or not np.allclose(r.sum(axis=1), 0.0):
            raise PredictionError(
                'mode rates must be a generator: off-diagonal rates >= 0, rows summing to 0'
            )
        for name in (
            'stationary_psd',
            'restart_speed_std',
            'acceleration_psd',
            'acceleration_std',
            'jerk_psd',
            'lateral_acceleration_std',
            'lateral_acceleration_psd',
            'lateral_jerk_psd',
        ):
            if getattr(self, name) is None:
                continue
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0.0):
                raise PredictionError(f'{name} must be finite and > 0, got {v}')
        lam, vec = np.linalg.eig(r)
        object.__setattr__(self, '_eig', (lam, vec, np.linalg.inv(vec)))

    @property
    def anisotropic(self) -> bool:
        """Whether the lateral noise differs from the along-track noise."""
        return any(
            getattr(self, f'lateral_{n}') is not None
            for n in ('acceleration_std', 'acceleration_psd', 'jerk_psd')
        )

    def lateral(self, name: str) -> float:
        """The lateral value of ``name`` (the along-track one where none is given)."""
        v = getattr(self, f'lateral_{name}')
        return float(getattr(self, name) if v is None else v)

    def grid(self, step: float, track: bool = False) -> MomentGrid:
        """The composed step maps of this mode set for ``step`` (in the track frame if
        ``track``), shared by every predictor that uses it (they cost a few ms to build and
        never change)."""
        grids: dict[tuple[float, bool], MomentGrid] = self.__dict__.setdefault('_grids', {})
        if (step, track) not in grids:
            grids[step, track] = MomentGrid(self, step, track=track)
        return grids[step, track]

    def transition(self, dt: float) -> Array:
        """``M(dt) = expm(rates dt)`` (3, 3), row-stochastic."""
        out: Array = self.transitions(np.array([dt]))[0]
        return out

    def transitions(self, dts: Array) -> Array:
        """``M(dt)`` for each of ``dts`` (K,): (K, 3, 3)."""
        w, v, vi = self._eig  # type: ignore[attr-defined]
        m = np.real((v[None] * np.exp(np.multiply.outer(dts, w))[:, None, :]) @ vi)
        m = np.clip(m, 0.0, None)
        out: Array = m / m.sum(axis=2, keepdims=True)
        return out

    def models(self, dt: float) -> tuple[Array, Array]:
        """Stacked F (3, 6, 6) and Q (3, 6, 6) of S, CV and CA over ``dt`` seconds."""
        F, Q = self.models_batch(np.array([dt]))
        return F[0], Q[0]

    def models_batch(self, dts: Array, track: bool = False) -> tuple[Array, Array]:
        """F (K, 3, 6, 6) and Q (K, 3, 6, 6) for each of ``dts`` (K,).

        Every entry is a polynomial of degree <= 5 in dt; the coefficients are found once
        from :meth:`models_explicit` (it runs on every prediction, so two matrix products
        instead of some twenty array assignments).
        """
        coefs: dict[bool, Array] = self.__dict__.setdefault('_coefs', {})
        coef = coefs.get(track)
        if coef is None:
            nodes = np.arange(6, dtype=np.float64)
            F, Q = self.models_explicit(nodes, track)
            vander = np.vander(nodes, 6, increasing=True)
            coef = np.linalg.solve(vander, np.concatenate([F, Q], axis=1).reshape(6, -1))
            coefs[track] = coef
        powers = np.asarray(dts, dtype=np.float64)[:, None] ** np.arange(6)
        both = (powers @ coef).reshape(len(dts), 6, 6, 6)
        return both[:, :3], both[:, 3:]

    def models_explicit(self, dts: Array, track: bool = False) -> tuple[Array, Array]:
        """F and Q as written in the module docstring (the reference of :meth:`models_batch`);
        with ``track``, the second axis (lateral) takes the lateral noise."""
        F, q = self._axis_models(dts, self.acceleration_std, self.acceleration_psd, self.jerk_psd)
        Q = np.zeros_like(F)
        Q[..., :3, :3] = q
        if track:
            q = self._axis_models(
                dts,
                self.lateral('acceleration_std'),
                self.lateral('acceleration_psd'),
                self.lateral('jerk_psd'),
            )[1]
        Q[..., 3:, 3:] = q
        return F, Q

    def _axis_models(
        self, dts: Array, acceleration_std: float, qa: float, qj: float
    ) -> tuple[Array, Array]:
        """F (K, 3, 6, 6) and one axis's Q (K, 3, 3, 3)."""
        k = len(dts)
        dt = dts
        d2, d3 = dt * dt, dt * dt * dt
        d4, d5 = d3 * dt, d3 * d2
        f = np.zeros((k, 3, 3, 3))
        q = np.zeros((k, 3, 3, 3))
        f[:, :, 0, 0] = 1.0  # position carries over in every mode
        q[:, 0, 0, 0] = self.stationary_psd * dt
        q[:, 0, 1, 1] = self.restart_speed_std**2
        q[:, 0, 2, 2] = acceleration_std**2
        q[:, 1, 2, 2] = acceleration_std**2  # the acceleration CV would take up
        f[:, 1:, 1, 1] = 1.0
        f[:, 1:, 0, 1] = dt[:, None]
        f[:, 2, 1, 2] = dt
        f[:, 2, 0, 2] = d2 / 2
        f[:, 2, 2, 2] = 1.0
        q[:, 1, 0, 0], q[:, 1, 1, 1] = qa * d3 / 3, qa * dt
        q[:, 1, 0, 1] = q[:, 1, 1, 0] = qa * d2 / 2
        q[:, 2, 0, 0], q[:, 2, 1, 1], q[:, 2, 2, 2] = qj * d5 / 20, qj * d3 / 3, qj * dt
        q[:, 2, 0, 1] = q[:, 2, 1, 0] = qj * d4 / 8
        q[:, 2, 0, 2] = q[:, 2, 2, 0] = qj * d3 / 6
        q[:, 2, 1, 2] = q[:, 2, 2, 1] = qj * d2 / 2
        F = np.zeros((k, 3, 6, 6))
        F[..., :3, :3] = F[..., 3:, 3:] = f
        return F, q


def track_rotation(heading: float) -> Array:
    """T (6, 6) taking a state from the world frame to the track frame (first axis along
    ``heading``, rad, second to its left): ``x_track = T x_world``."""
    c, s = math.cos(heading), math.sin(heading)
    # kron([[c, s], [-s, c]], I3), written out: np.kron's reshapes cost 0.1 ms a call here.
    out: Array = np.zeros((6, 6))
    i = np.arange(3)
    out[i, i] = out[i + 3, i + 3] = c
    out[i, i + 3] = s
    out[i + 3, i] = -s
    return out


def generator(off_diagonal: list[list[float]]) -> Array:
    """A generator matrix from its off-diagonal rates (the diagonal is ignored)."""
    r = np.asarray(off_diagonal, dtype=np.float64).copy()
    np.fill_diagonal(r, 0.0)
    np.fill_diagonal(r, -r.sum(axis=1))
    return r


@dataclass
class ModeStates:
    """Mode-conditioned estimates: ``x`` (3, 6), ``P`` (3, 6, 6), probabilities ``mu`` (3,)."""

    x: Array
    P: Array
    mu: Array

    def combined(self) -> tuple[Array, Array]:
        """The moment-matched mean (6,) and covariance (6, 6) over the modes."""
        x = self.mu @ self.x
        d = self.x - x
        P = np.einsum('j,jab->ab', self.mu, self.P) + np.einsum('j,ja,jb->ab', self.mu, d, d)
        return x, P


def mix_and_predict(s: ModeStates, M: Array, F: Array, Q: Array) -> ModeStates:
    """IMM mixing with transition matrix ``M`` and mode-matched prediction with ``F``, ``Q``
    (3, 6, 6); the result's ``mu`` are the predicted mode probabilities ``c``."""
    c = np.maximum(M.T @ s.mu, 1e-300)
    w = M * s.mu[:, None] / c[None, :]  # w_ij = P(mode i before | mode j now)
    x0 = w.T @ s.x
    d = (s.x[None, :, :] - x0[:, None, :]) * np.sqrt(w.T)[:, :, None]  # (j, i, 6)
    P0 = (w.T @ s.P.reshape(3, 36)).reshape(3, 6, 6) + d.transpose(0, 2, 1) @ d
    x = (F @ x0[:, :, None])[:, :, 0]
    P = F @ P0 @ F.transpose(0, 2, 1) + Q
    return ModeStates(x, P, c)


def _inverse2(S: Array) -> tuple[Array, Array]:
    """Inverses and determinants of a stack of symmetric 2x2 matrices (..., 2, 2)."""
    a, b, c = S[..., 0, 0], S[..., 0, 1], S[..., 1, 1]
    det = a * c - b * b
    inv = np.empty_like(S)
    inv[..., 0, 0], inv[..., 1, 1] = c / det, a / det
    inv[..., 0, 1] = inv[..., 1, 0] = -b / det
    return inv, det


def update(s: ModeStates, z: Array, r: float) -> tuple[ModeStates, float]:
    """Mode-matched Kalman updates with fix ``z`` (noise variance ``r`` per axis) and the new
    mode probabilities.

    Returns:
        The updated states and the squared Mahalanobis distance of ``z`` from the mixture's
        predicted fix (to gate outliers: if it is too large, keep ``s``).
    """
    zs = s.x[:, ::3]  # predicted fix per mode (p_x, p_y)
    y = z - zs
    PHt = s.P[:, :, ::3]
    S = PHt[:, ::3, :].copy()
    S[:, 0, 0] += r
    S[:, 1, 1] += r
    Si, det = _inverse2(S)
    # The mixture's predicted fix, for the outlier gate.
    e = s.mu @ y
    dz = y - e
    Sbar_inv, _ = _inverse2((s.mu @ S.reshape(3, 4)).reshape(2, 2) + (dz.T * s.mu) @ dz)
    d2_mix = float(e @ Sbar_inv @ e)
    K = PHt @ Si
    Ky = K @ y[:, :, None]
    x = s.x + Ky[:, :, 0]
    P = s.P - K @ PHt.transpose(0, 2, 1)  # (I - K H) P
    d2 = (y[:, :, None] * (Si @ y[:, :, None])).sum(axis=(1, 2))
    like = np.maximum(np.exp(-0.5 * d2) / (2.0 * math.pi * np.sqrt(det)), 1e-300)
    mu = s.mu * like
    total = float(mu.sum())
    mu = mu / total if total > 0.0 and math.isfinite(total) else s.mu.copy()
    return ModeStates(x, 0.5 * (P + P.transpose(0, 2, 1)), mu), d2_mix


def _step_operators(
    modes: ModeSet, dts: Array, track: bool = False
) -> tuple[Array, Array, Array, Array]:
    """Per step length: transposed transition (K, 3, 3), augmented G (K, 3, 7, 7), its
    transpose, and Q (K, 3, 6, 6)."""
    F, Q = modes.models_batch(dts, track)
    G = np.zeros((len(dts), 3, 7, 7))
    G[..., :6, :6] = F
    G[..., 6, 6] = 1.0
    return modes.transitions(dts).transpose(0, 2, 1), G, G.transpose(0, 1, 3, 2), Q


def _advance(A: Array, Mt: Array, G: Array, Gt: Array, Q: Array) -> Array:
    """One step of the moment recursion (any leading batch shape)."""
    shape = A.shape
    B = (Mt @ A.reshape(*shape[:-2], 49)).reshape(shape)
    out: Array = G @ B @ Gt
    out[..., :6, :6] += B[..., 6:, 6:] * Q
    return out


def step_grid(lead: float, step: float) -> float:
    """The moment recursion's step at ``lead`` seconds ahead: ``step`` for the first 2 s, then
    twice that to 4 s, then four times (switching matters most soon)."""
    return step if lead < 2.0 - 1e-9 else (2.0 * step if lead < 4.0 - 1e-9 else 4.0 * step)


def _step_map(modes: ModeSet, dt: float, track: bool = False) -> Array:
    """The moment recursion over one step of ``dt`` as one linear map on the stacked
    row-major ``A_j`` (147,): ``vec(G B G^T) = (G kron G) vec(B)``, plus ``Q`` times
    ``B[6, 6]``, after mixing ``B_j = sum_i M_ij A_i``."""
    Mt, G, _, Q = _step_operators(modes, np.array([dt]), track)
    L = np.zeros((147, 147))
    for j in range(3):
        K = np.kron(G[0, j], G[0, j])
        K[:, 48] += np.pad(Q[0, j], ((0, 1), (0, 1))).reshape(49)
        for i in range(3):
            L[49 * j : 49 * j + 49, 49 * i : 49 * i + 49] = Mt[0, j, i] * K
    return L


class MomentGrid:
    """Composed step maps from now to the points of the step grid (:func:`step_grid`), built
    once per mode set and step and grown as far ahead as predictions go (up to ``horizon``
    seconds; further predictions step on one by one). With ``track``, the maps are those of
    the track frame (first axis along the velocity, second lateral)."""

    def __init__(
        self, modes: ModeSet, step: float, horizon: float = 60.0, track: bool = False
    ) -> None:
        self.modes = modes
        self.track = track
        self.step = step
        self.horizon = horizon
        self.times = [0.0]
        self.maps = [np.eye(147)]
        self.stack = np.eye(147)  # the maps one above the other (N * 147, 147)

    def index(self, lead: float) -> int:
        """The last grid point at or before ``lead``, growing the grid as needed."""
        while self.times[-1] <= min(lead, self.horizon) + 1e-9:
            dt = step_grid(self.times[-1], self.step)
            if self.times[-1] + dt > lead + 1e-9:
                break
            self.maps.append(_step_map(self.modes, dt, self.track) @ self.maps[-1])
            self.times.append(self.times[-1] + dt)
            self.stack = np.concatenate(self.maps)
        return int(np.searchsorted(self.times, lead + 1e-9, side='right')) - 1


def propagate_moments(
    s: ModeStates,
    modes: ModeSet,
    leads: Array,
    origin: Array,
    grid: MomentGrid,
    heading: float = 0.0,
) -> Array:
    """Switching-aware moments of the position ``leads`` seconds ahead.

    Time ahead is cut into the steps of ``grid``; the mode may switch at every step boundary
    (continuous-time switching is approached as the steps shrink). Each lead ends with a step
    of its own from the last grid point before it.

    Args:
        s: the mode states now.
        modes: the mode set.
        leads: (K,) times ahead, s (>= 0).
        origin: (2,) position subtracted from the positions, for precision.
        grid: the composed step maps (kept by the caller between calls).
        heading: direction of travel (rad, world), the track frame's first axis, used if
            ``grid.track``.

    Returns:
        (K, 3, 3): ``[[E[zz^T], E[z]], [E[z]^T, 1]]`` of the position ``z`` relative to
        ``origin``, over every mode sequence.
    """
    x = s.x.copy()
    x[:, ::3] -= origin
    P = s.P
    c, si = math.cos(heading), math.sin(heading)
    if grid.track:  # into the track frame: along = (c, s), lateral = (-s, c)
        T = track_rotation(heading)
        x = x @ T.T
        P = T @ P @ T.T
    A = np.zeros((3, 7, 7))
    A[:, :6, :6] = P + x[:, :, None] * x[:, None, :]
    A[:, :6, 6] = A[:, 6, :6] = x
    A[:, 6, 6] = 1.0
    A *= s.mu[:, None, None]
    idx = [grid.index(float(lead)) for lead in leads]
    last = max(idx) + 1
    states = (grid.stack[: 147 * last] @ A.reshape(147)).reshape(last, 3, 7, 7)
    before = states[idx]
    rest = leads - np.array([grid.times[i] for i in idx])
    while np.any(rest > 1e-9):  # the last step of each lead (several beyond the grid)
        go = rest > 1e-9
        at = leads[go] - rest[go]
        dt = np.array(
            [min(r, step_grid(float(a), grid.step)) for r, a in zip(rest[go], at, strict=True)]
        )
        before[go] = _advance(before[go], *_step_operators(modes, dt, grid.track))
        rest[go] -= dt
    sel = np.array([0, 3, 6])
    out: Array = before.sum(axis=1)[:, sel][:, :, sel]
    if grid.track:  # back to the world frame
        R = np.eye(3)
        R[:2, :2] = [[c, -si], [si, c]]
        out = R @ out @ R.T
    return out
