"""The prediction suite's true object paths, by kind (pure core, seeded).

Beside the paper's straight lines and parabolas at constant path speed (``paper_line``,
``paper_parabola``: 10-20 mm/s), the manoeuvres of a cell: stops of 1, 3 and 6 s halfway
(``stop_1s``, ``stop_3s``, ``stop_6s``), reversals, speed steps (8 then 20 mm/s), s-curves,
circular arcs and random smooth paths, all inside the table and within 20 mm/s, with the
stream's acceleration ramps (:func:`activesurv_sim.stream.random_path`).
"""

from __future__ import annotations

import numpy as np

from activesurv_sim.stream import _X0, _X1, _Y0, _Y1, random_path, travel
from activesurv_sim.xytable import TimedPath
from activesurv_stages.errors import ConfigError

SUITE_KINDS = (
    'paper_line',
    'paper_parabola',
    'stop_1s',
    'stop_3s',
    'stop_6s',
    'reversal',
    'speed_change',
    's_curve',
    'arc',
    'smooth',
)


def _constant_speed(xs: np.ndarray, ys: np.ndarray, speed: float) -> TimedPath:
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xs), np.diff(ys)))])
    t = np.linspace(0.0, s[-1] / speed, 2000)
    return TimedPath(
        t, np.column_stack([np.interp(speed * t, s, xs), np.interp(speed * t, s, ys)])
    )


def suite_path(kind: str, rng: np.random.Generator) -> TimedPath:
    """One path of the given suite kind, drawn from ``rng``.

    Raises:
        ConfigError: for an unknown kind.
    """
    if kind == 'paper_line':
        a = np.array([rng.uniform(0.02, 0.2), rng.uniform(0.02, 0.18)])
        b = np.array([rng.uniform(0.3, 0.48), rng.uniform(0.02, 0.18)])
        u = np.linspace(0.0, 1.0, 200)
        return _constant_speed(
            a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), rng.uniform(0.01, 0.02)
        )
    if kind == 'paper_parabola':
        x0, x1 = rng.uniform(0.02, 0.12), rng.uniform(0.38, 0.48)
        depth = rng.uniform(0.04, 0.16) * rng.choice([-1.0, 1.0])
        xs = np.linspace(x0, x1, 4000)
        c = depth / (0.5 * (x1 - x0)) ** 2
        ys = np.clip(0.1 - depth / 2 + c * (xs - 0.5 * (x0 + x1)) ** 2, 0.0, 0.2)
        return _constant_speed(xs, ys, rng.uniform(0.01, 0.02))
    if kind.startswith('stop_') and kind in SUITE_KINDS:
        wait = float(kind[5:-1])
        xa, xb = (_X0, _X1) if rng.random() < 0.5 else (_X1, _X0)
        ya, yb = rng.uniform(_Y0, _Y1, size=2)
        f = rng.uniform(0.3, 0.7)
        pts = np.array([[xa, ya], [xa + f * (xb - xa), ya + f * (yb - ya)], [xb, yb]])
        return travel(pts, [0.02, 0.02], {1: wait}, 0.02)
    if kind in SUITE_KINDS:
        return random_path(kind, rng)
    raise ConfigError(f'unknown path kind {kind!r}; use one of {SUITE_KINDS}')


MANOEUVRES = ('stop', 'reversal', 'speed_change', 'stop_and_go')


def manoeuvre_path(kind: str, speed: float = 0.02, acceleration: float = 0.02) -> TimedPath:
    """The paper's Set A parabola (x 0.13 -> 0.37 m, apex y = 0.09 m) with a manoeuvre, for
    experiments on the Set A cameras (``experiment --trajectory``):

    * ``stop``: waits 3 s at the apex;
    * ``reversal``: turns back 6 cm at the apex, then goes on;
    * ``speed_change``: 8 mm/s for the first 5 cm, then ``speed``;
    * ``stop_and_go``: waits 1 s at a third and at two thirds of the way.

    Raises:
        ConfigError: for an unknown kind.
    """
    xs = np.linspace(0.13, 0.37, 61)
    pts = np.column_stack([xs, 0.09 - (0.04 / 0.12**2) * (xs - 0.25) ** 2])
    n = len(pts) - 1
    if kind == 'stop':
        return travel(pts, [speed] * n, {30: 3.0}, acceleration)
    if kind == 'reversal':
        i = 30
        back = [pts[i - k] for k in range(1, 16)]
        route = np.vstack([pts[: i + 1], back, pts[i - 14 :]])
        turns = {i: 0.0, i + len(back): 0.0}
        return travel(route, [speed] * (len(route) - 1), turns, acceleration)
    if kind == 'speed_change':
        return travel(pts, [min(0.008, speed)] * 12 + [speed] * (n - 12), {}, acceleration)
    if kind == 'stop_and_go':
        return travel(pts, [speed] * n, {20: 1.0, 40: 1.0}, acceleration)
    raise ConfigError(f'unknown manoeuvre {kind!r}; use one of {MANOEUVRES}')


def write_csv(path: TimedPath, out: str, step: float = 0.02) -> None:
    """Write ``path`` as a ``t,x,y`` CSV sampled every ``step`` s (``experiment --trajectory``)."""
    ts = np.arange(0.0, path.duration + 1e-9, step)
    rows = ['t,x,y'] + [
        f'{t:.3f},{x:.6f},{y:.6f}' for t, (x, y) in zip(ts, map(path.position, ts), strict=True)
    ]
    with open(out, 'w') as f:
        f.write('\n'.join(rows) + '\n')
