"""Initial-pose determination (paper Section II-E): place the cameras for an expected path.

Given the demand points expected along a rough prior trajectory, each camera gets the initial
configuration that maximises its summed visibility over them. For demand j that visibility is the
best the camera can *achieve* from that initial configuration in the time ``t_j - start``, with
its motion class's speeds, plus a quarter of what it sees of the path from the initial pose
itself (the tie-break for fast cameras, which can reach almost anything in time). A slow
camera is placed where it can keep up, ahead of the target (the paper's Fig. 8-9
observation); a fast camera near where it is needed first. Cameras are placed independently
(their mounts differ, and the dispatcher shares them out online), except the static system.
Its cameras can never move, so they are placed together: a coordinate ascent maximises the
coverage of the demands (each demand's first view counts most, its k-th least, more count
nothing), then the summed visibility. This is the paper's "the target can be imaged by at least
three cameras at any demand point", as far as the optics allow (docs/design-choices.md).

The search is a grid over the joint space, then a finer grid around the best cell.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import permutations

import numpy as np
from numpy.typing import NDArray

from activesurv_common.occlusion import Obstacle
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.best_pose import aim_yaw, best_achievable_pose, view_batch
from activesurv_dispatch.errors import DispatchConfigError
from activesurv_dispatch.planner import Demand
from activesurv_dispatch.sensors import Sensor, Setup

Array = NDArray[np.float64]
ALREADY_WEIGHT = 0.25


def _grid(
    sensor: Sensor, n_lin: int, n_yaw: int, centre: Array | None = None, span: Array | None = None
) -> Array:
    axes = []
    for i, lim in enumerate(sensor.limits):
        n = n_lin if (sensor.has_linear and i == 0) else n_yaw
        if centre is None or span is None:
            lo, hi = lim.min_position, lim.max_position
        else:
            lo = max(lim.min_position, centre[i] - span[i])
            hi = min(lim.max_position, centre[i] + span[i])
        axes.append(np.linspace(lo, hi, n))
    mesh = np.meshgrid(*axes, indexing='ij')
    return np.column_stack([m.ravel() for m in mesh])


def _with_aimed(sensor: Sensor, cands: Array, expected: Sequence[Demand]) -> Array:
    """Add, for every linear position, the yaws aimed at the path's first, middle and last
    demand points (a coarse yaw grid misses a 7-degree field of view)."""
    lin = np.unique(cands[:, 0]) if sensor.has_linear else np.zeros(1)
    picks = [expected[0], expected[len(expected) // 2], expected[-1]]
    extra = []
    for d in picks:
        yaw = aim_yaw(sensor, lin, d.target)
        lim = sensor.limits[-1]
        yaw = np.clip(yaw, lim.min_position, lim.max_position)
        extra.append(np.column_stack([lin, yaw]) if sensor.has_linear else yaw[:, None])
    return np.vstack([cands, *extra])


def _scores(
    sensor: Sensor,
    cands: Array,
    expected: Sequence[Demand],
    start: float,
    model: SensorModel,
    radius: float,
    occluders: Sequence[Obstacle] = (),
) -> Array:
    if not sensor.moves:
        total = np.zeros(len(cands))
        for d in expected:
            total += view_batch(sensor, cands, d.target, radius, model, occluders=occluders)[0]
        return total
    achievable = np.array(
        [
            sum(
                best_achievable_pose(
                    sensor, q, d.target, d.time - start, model, radius, 9, occluders
                ).visibility
                for d in expected
            )
            for q in cands
        ]
    )
    # What the initial pose already sees of the expected path breaks the ties of a fast camera,
    # which can reach almost anything in time: prefer watching the path over an arbitrary pose.
    already = np.zeros(len(cands))
    for d in expected:
        already += view_batch(sensor, cands, d.target, radius, model, occluders=occluders)[0]
    return np.asarray(achievable + ALREADY_WEIGHT * already, dtype=np.float64)


def _static_coverage(
    setup: Setup, model: SensorModel, expected: Sequence[Demand], k: int
) -> dict[str, Array]:
    radius = setup.marker_radius
    cands: dict[str, Array] = {}
    vis: dict[str, Array] = {}
    for s in setup.sensors:
        grid = _grid(s, 31, 241)
        cands[s.camera_id] = grid
        vis[s.camera_id] = np.array(
            [
                view_batch(s, grid, d.target, radius, model, occluders=setup.obstacles)[0]
                for d in expected
            ]
        ).T  # (candidates, demands)
    scale = max(float(max(v.max() for v in vis.values())), 1e-300) * len(expected)
    seen = {c: (v > 0).astype(int) for c, v in vis.items()}
    # Coverage with diminishing returns (k = 3: the 1st camera on a demand is worth 3, the
    # 2nd 2, the 3rd 1, more nothing), so every demand gets a second view before any a third.
    worth = np.concatenate(
        [
            [0.0],
            np.cumsum(np.arange(k, 0, -1, dtype=float)),
            np.full(len(setup.sensors) + 1, float(k * (k + 1) // 2)),
        ]
    )

    def gain(counts: NDArray[np.int_]) -> Array:
        return np.asarray(worth[np.minimum(counts, len(worth) - 1)].sum(axis=-1), dtype=np.float64)

    def total(sel: dict[str, int]) -> float:
        counts = sum(seen[c][i] for c, i in sel.items())
        return float(gain(np.asarray(counts))) + sum(
            float(vis[c][i].sum()) for c, i in sel.items()
        ) / (scale * len(vis))

    def ascend(sel: dict[str, int]) -> dict[str, int]:
        for _ in range(8):
            changed = False
            for c, v in vis.items():
                others = sum(seen[o][sel[o]] for o in vis if o != c)
                score = gain(others[None, :] + seen[c]) + v.sum(axis=1) / scale
                best = int(np.argmax(score))
                if best != sel[c] and score[best] > score[sel[c]] + 1e-12:
                    sel[c], changed = best, True
            if not changed:
                break
        return sel

    # Several starts (greedy placement in every camera order, for up to 5 cameras; otherwise
    # one order), each polished by coordinate ascent: the coverage landscape has local optima.
    orders = list(permutations(vis)) if len(vis) <= 5 else [tuple(vis)]
    best_sel: dict[str, int] | None = None
    for order in orders:
        sel: dict[str, int] = {}
        counts = np.zeros(len(expected), dtype=int)
        for c in order:
            score = gain(counts[None, :] + seen[c]) + vis[c].sum(axis=1) / scale
            sel[c] = int(np.argmax(score))
            counts = counts + seen[c][sel[c]]
        sel = ascend(sel)
        if best_sel is None or total(sel) > total(best_sel):
            best_sel = dict(sel)
    assert best_sel is not None
    return {c: cands[c][i] for c, i in best_sel.items()}


def initial_poses(
    setup: Setup, model: SensorModel, expected: Sequence[Demand], start: float = 0.0, k: int = 3
) -> dict[str, Array]:
    """Initial joint positions per camera for the expected demand points.

    Raises:
        DispatchConfigError: without expected demand points.
    """
    if not expected:
        raise DispatchConfigError('initial-pose determination needs expected demand points')
    if not any(s.moves for s in setup.sensors):
        return _static_coverage(setup, model, expected, k)
    out: dict[str, Array] = {}
    radius = setup.marker_radius
    for s in setup.sensors:
        coarse = (31, 121) if not s.moves else (11, 25)
        cands = _with_aimed(s, _grid(s, *coarse), expected)
        scores = _scores(s, cands, expected, start, model, radius, setup.obstacles)
        best = cands[int(np.argmax(scores))]
        step = np.array(
            [
                (lim.max_position - lim.min_position) / (n - 1)
                for lim, n in zip(
                    s.limits, ([coarse[0]] if s.has_linear else []) + [coarse[1]], strict=True
                )
            ]
        )
        fine = _grid(s, 7, 7, best, step)
        fine_scores = _scores(s, fine, expected, start, model, radius, setup.obstacles)
        j = int(np.argmax(fine_scores))
        out[s.camera_id] = fine[j] if fine_scores[j] >= scores.max() else best
    return out
