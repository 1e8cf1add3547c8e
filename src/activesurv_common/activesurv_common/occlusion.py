"""Things in the way: obstacles of the cell and lines of sight through them (pure core).

The paper leaves occlusion out ("an unobstructed single-object dynamic environment", Section
II-A) although its visibility measure (eq. 1) has a case for it: a camera whose line of sight
to the target is blocked has visibility 0. Here the cell may hold fixed obstacles, solids in the
world frame (SI units), as a rig or hardware file lists them::

    obstacles:
      - {kind: box, centre: [x, y, z], size: [dx, dy, dz]}        # axis-aligned
      - {kind: cylinder, centre: [x, y, z], radius: r, height: h} # vertical axis

``centre`` is the middle of the solid. A line of sight is the segment from a camera's optical
centre to the marker centre; it is blocked when it passes through any solid (touching a face
counts; its two ends are left out, so a marker on a solid's face is not blocked by that solid).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from activesurv_common.geometry import cross3

Array = NDArray[np.float64]
KINDS = ('box', 'cylinder')
_END = 1e-6  # fraction of a segment left out at each end


class ObstacleError(ValueError):
    """An obstacle description is malformed."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned box: its centre and its full size along x, y, z (m)."""

    centre: tuple[float, float, float]
    size: tuple[float, float, float]

    @property
    def low(self) -> Array:
        return np.asarray(self.centre) - 0.5 * np.asarray(self.size)

    @property
    def high(self) -> Array:
        return np.asarray(self.centre) + 0.5 * np.asarray(self.size)


@dataclass(frozen=True)
class Cylinder:
    """A cylinder with a vertical axis: the centre of the solid, its radius and height (m)."""

    centre: tuple[float, float, float]
    radius: float
    height: float


Obstacle = Box | Cylinder


def _vector(value: Any, what: str) -> tuple[float, float, float]:
    try:
        v = [float(x) for x in value]
    except (TypeError, ValueError) as exc:
        raise ObstacleError(f'{what} must be three numbers, got {value!r}') from exc
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ObstacleError(f'{what} must be three finite numbers, got {value!r}')
    return v[0], v[1], v[2]


def _positive(value: Any, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ObstacleError(f'{what} must be a number, got {value!r}') from exc
    if not (math.isfinite(v) and v > 0.0):
        raise ObstacleError(f'{what} must be finite and > 0, got {value!r}')
    return v


def obstacle_from_dict(item: Mapping[str, Any], where: str = 'obstacle') -> Obstacle:
    """One obstacle from its YAML mapping.

    Raises:
        ObstacleError: for an unknown kind, a missing key or a bad value.
    """
    if not isinstance(item, Mapping):
        raise ObstacleError(f'{where} must be a mapping, got {item!r}')
    kind = item.get('kind')
    keys = {'box': {'kind', 'centre', 'size'}, 'cylinder': {'kind', 'centre', 'radius', 'height'}}
    if kind not in keys:
        raise ObstacleError(f'{where}: kind must be one of {KINDS}, got {kind!r}')
    missing = keys[kind] - set(item)
    extra = set(item) - keys[kind]
    if missing or extra:
        raise ObstacleError(
            f'{where} ({kind}): '
            + (f'missing {sorted(missing)}' if missing else f'unknown keys {sorted(extra)}')
        )
    centre = _vector(item['centre'], f'{where}.centre')
    if kind == 'box':
        size = _vector(item['size'], f'{where}.size')
        for axis, s in zip('xyz', size, strict=True):
            _positive(s, f'{where}.size {axis}')
        return Box(centre, size)
    return Cylinder(
        centre,
        _positive(item['radius'], f'{where}.radius'),
        _positive(item['height'], f'{where}.height'),
    )


def obstacles_from_list(items: Any, where: str = 'obstacles') -> tuple[Obstacle, ...]:
    """The obstacles of a file's ``obstacles`` list (None or missing: none).

    Raises:
        ObstacleError: if it is not a list or one of its items is bad.
    """
    if items is None:
        return ()
    if not isinstance(items, Sequence) or isinstance(items, (str, bytes)):
        raise ObstacleError(f'{where} must be a list, got {items!r}')
    return tuple(obstacle_from_dict(o, f'{where}[{i}]') for i, o in enumerate(items))


def load_obstacles(path: str | Path) -> tuple[Obstacle, ...]:
    """The ``obstacles`` list of a YAML file (a rig, set-up or hardware file); '' : none.

    Raises:
        ObstacleError: if the file cannot be read or its list is bad.
    """
    if not str(path):
        return ()
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ObstacleError(f'cannot read obstacles from {path}: {exc}') from exc
    if not isinstance(data, Mapping):
        raise ObstacleError(f'{path}: expected a mapping with an "obstacles" list')
    return obstacles_from_list(data.get('obstacles'), f'{path}: obstacles')


def obstacle_to_dict(o: Obstacle) -> dict[str, Any]:
    if isinstance(o, Box):
        return {'kind': 'box', 'centre': list(o.centre), 'size': list(o.size)}
    return {'kind': 'cylinder', 'centre': list(o.centre), 'radius': o.radius, 'height': o.height}


def obstacles_to_list(obstacles: Iterable[Obstacle]) -> list[dict[str, Any]]:
    return [obstacle_to_dict(o) for o in obstacles]


PLATE_THICKNESS = 0.006  # m: a marker plate as a solid
PLATE_HALF_SIZE = 0.03  # m: half side of an object's (square) marker plates


def plate_box(centre: ArrayLike, normal: ArrayLike, half_size: float) -> Box:
    """The axis-aligned box around a square plate of ``half_size`` centred at ``centre`` with
    a horizontal edge (a marker plate of another object, standing in the way)."""
    c = np.asarray(centre, dtype=np.float64).reshape(3)
    n = np.asarray(normal, dtype=np.float64).reshape(3)
    n = n / max(float(np.linalg.norm(n)), 1e-12)
    x = cross3([0.0, 0.0, 1.0], n)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
    y = cross3(n, x)
    extent = half_size * (np.abs(x) + np.abs(y)) + 0.5 * PLATE_THICKNESS * np.abs(n)
    size = 2.0 * extent
    return Box(
        (float(c[0]), float(c[1]), float(c[2])),
        (float(size[0]), float(size[1]), float(size[2])),
    )


def _box_interval(a: Array, d: Array, low: Array, high: Array) -> tuple[Array, Array]:
    """Per segment, the parameter interval [s0, s1] inside the box (slab method)."""
    s0 = np.full(len(a), -np.inf)
    s1 = np.full(len(a), np.inf)
    for k in range(3):
        dk = d[:, k]
        parallel = np.abs(dk) < 1e-15  # (a subnormal dk overflows the quotient: masked here)
        with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
            t_lo = (low[k] - a[:, k]) / dk
            t_hi = (high[k] - a[:, k]) / dk
        near = np.where(parallel, -np.inf, np.minimum(t_lo, t_hi))
        far = np.where(parallel, np.inf, np.maximum(t_lo, t_hi))
        outside = parallel & ((a[:, k] < low[k]) | (a[:, k] > high[k]))
        near = np.where(outside, np.inf, near)
        s0 = np.maximum(s0, near)
        s1 = np.minimum(s1, far)
    return s0, s1


def _cylinder_interval(a: Array, d: Array, c: Cylinder) -> tuple[Array, Array]:
    """Per segment, the parameter interval inside the (finite, vertical) cylinder."""
    cx, cy, cz = c.centre
    z_lo, z_hi = cz - 0.5 * c.height, cz + 0.5 * c.height
    s0, s1 = _box_interval(
        a,
        d,
        np.array([-np.inf, -np.inf, z_lo]),
        np.array([np.inf, np.inf, z_hi]),
    )
    px, py = a[:, 0] - cx, a[:, 1] - cy
    dx, dy = d[:, 0], d[:, 1]
    qa = dx * dx + dy * dy
    qb = 2.0 * (px * dx + py * dy)
    qc = px * px + py * py - c.radius * c.radius
    vertical = qa < 1e-24
    disc = qb * qb - 4.0 * qa * qc
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        r0 = (-qb - root) / (2.0 * qa)
        r1 = (-qb + root) / (2.0 * qa)
    r0 = np.where(vertical, np.where(qc <= 0.0, -np.inf, np.inf), np.where(disc < 0, np.inf, r0))
    r1 = np.where(vertical, np.where(qc <= 0.0, np.inf, -np.inf), np.where(disc < 0, -np.inf, r1))
    return np.maximum(s0, r0), np.minimum(s1, r1)


def blocked(
    starts: ArrayLike, ends: ArrayLike, obstacles: Sequence[Obstacle]
) -> NDArray[np.bool_]:
    """Whether each segment ``starts[i] -> ends[i]`` passes through any obstacle.

    ``starts`` and ``ends`` are (N, 3) or (3,) (broadcast against each other).
    """
    a = np.atleast_2d(np.asarray(starts, dtype=np.float64))
    b = np.atleast_2d(np.asarray(ends, dtype=np.float64))
    a, b = np.broadcast_arrays(a, b)
    out = np.zeros(len(a), dtype=bool)
    if not obstacles:
        return out
    d = b - a
    for o in obstacles:
        if isinstance(o, Box):
            s0, s1 = _box_interval(a, d, o.low, o.high)
        else:
            s0, s1 = _cylinder_interval(a, d, o)
        lo = np.maximum(s0, _END)
        hi = np.minimum(s1, 1.0 - _END)
        out |= lo <= hi
    return out


def inflate(obstacles: Sequence[Obstacle], margin: float) -> tuple[Obstacle, ...]:
    """The obstacles grown by ``margin`` on every side (a line of sight that clears the grown
    solids clears the real ones by ``margin``: a marker of that radius is not cut)."""
    if margin <= 0.0:
        return tuple(obstacles)
    out: list[Obstacle] = []
    for o in obstacles:
        if isinstance(o, Box):
            size = (o.size[0] + 2 * margin, o.size[1] + 2 * margin, o.size[2] + 2 * margin)
            out.append(Box(o.centre, size))
        else:
            out.append(Cylinder(o.centre, o.radius + margin, o.height + 2 * margin))
    return tuple(out)


def rim_points(marker: ArrayLike, normal: ArrayLike, radius: float, n: int = 8) -> Array:
    """The centre and ``n`` points of the rim of a disc marker (``n + 1``, 3)."""
    c = np.asarray(marker, dtype=np.float64).reshape(3)
    z = np.asarray(normal, dtype=np.float64).reshape(3)
    z = z / max(float(np.linalg.norm(z)), 1e-12)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = cross3(z, helper)
    u /= np.linalg.norm(u)
    v = cross3(z, u)
    a = 2.0 * np.pi * np.arange(n) / n
    rim = c + radius * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)
    return np.vstack([c, rim])


def sight_blocked(
    cameras: ArrayLike,
    marker: ArrayLike,
    obstacles: Sequence[Obstacle],
    radius: float,
    normal: ArrayLike | None = None,
) -> NDArray[np.bool_]:
    """Whether each camera centre's view of a disc marker of ``radius`` centred at ``marker``
    is blocked or cut: with the marker's ``normal``, any of the lines of sight to its centre
    and eight rim points passes through an obstacle; without it (conservatively), the line
    of sight to the centre passes within ``radius`` of one."""
    centres = np.atleast_2d(np.asarray(cameras, dtype=np.float64))
    if normal is None:
        return blocked(centres, marker, inflate(obstacles, radius))
    out = np.zeros(len(centres), dtype=bool)
    for p in rim_points(marker, normal, radius):
        out |= blocked(centres, p, obstacles)
    return out


def inside(
    points: ArrayLike, obstacles: Sequence[Obstacle], margin: float = 0.0
) -> NDArray[np.bool_]:
    """Whether each point lies within ``margin`` of the inside of an obstacle."""
    p = np.atleast_2d(np.asarray(points, dtype=np.float64))
    out = np.zeros(len(p), dtype=bool)
    for o in obstacles:
        if isinstance(o, Box):
            out |= np.all((p >= o.low - margin) & (p <= o.high + margin), axis=1)
        else:
            cx, cy, cz = o.centre
            r = np.hypot(p[:, 0] - cx, p[:, 1] - cy)
            out |= (r <= o.radius + margin) & (np.abs(p[:, 2] - cz) <= 0.5 * o.height + margin)
    return out
