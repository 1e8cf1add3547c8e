"""A picture of the rig from a bag's frame tree (what Foxglove's 3D panel shows): the table,
each camera's frustum placed by /tf and /tf_static at one instant, the object, and the demand
points on the horizon then. ``activesurv report`` draws it for graph runs (``scene.png``).
"""

from __future__ import annotations

import bisect
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_common import frames
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_recording.bagio import read_bag


def _stamp(h: Any) -> float:
    return float(h.stamp.sec) + 1e-9 * float(h.stamp.nanosec)


def tree_at(bag: Path, t: float) -> dict[str, frames.Edge]:
    """The frame tree of ``bag`` at ``t`` (s): static edges, and each moving edge's latest
    transform at or before ``t``."""
    static: dict[str, frames.Edge] = {}
    moving: dict[str, list[tuple[float, frames.Edge]]] = {}
    for m in read_bag(bag, {'/tf', '/tf_static'}):
        for tr in m.msg.transforms:
            r, p = tr.transform.rotation, tr.transform.translation
            T = Transform.from_rt(matrix_from_quaternion([r.x, r.y, r.z, r.w]), [p.x, p.y, p.z])
            edge = frames.Edge(tr.header.frame_id, tr.child_frame_id, T)
            if m.topic == '/tf_static':
                static[edge.child] = edge
            else:
                moving.setdefault(edge.child, []).append((_stamp(tr.header), edge))
    tree = dict(static)
    for child, samples in moving.items():
        samples.sort(key=lambda s: s[0])
        i = bisect.bisect_right([s[0] for s in samples], t) - 1
        tree[child] = samples[max(i, 0)][1]
    return tree


def plot_scene(bag: Path, t: float, path: Path, title: str = '') -> Path:
    """Draw the rig at ``t`` into ``path``.

    Raises:
        BagError: for an unreadable bag; KeyError if the bag has no frame tree.
    """
    import matplotlib  # heavy: only when a figure is drawn

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    tree = tree_at(bag, t)
    fig = plt.figure(figsize=(8, 6))
    ax = fig.add_subplot(projection='3d')
    table = np.array([[0, 0, 0], [0.5, 0, 0], [0.5, 0.2, 0], [0, 0.2, 0], [0, 0, 0]])
    ax.plot(*table.T, color='k', lw=1)
    colours = ['tab:red', 'tab:blue', 'tab:green', 'tab:purple', 'tab:gray']
    optical = sorted(f for f in tree if f.endswith('_optical_frame'))
    for i, frame in enumerate(optical):
        T = frames.chain(tree.values(), frame)
        depth = 0.12 if frame != frames.OVERHEAD else 0.25
        half = np.array([0.32, 0.24]) * depth / 2.5  # a 7.3 x 5.5 deg field of view, enlarged
        corners = np.array([[sx * half[0], sy * half[1], depth] for sx, sy in
                            ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1))])  # fmt: skip
        world = np.array([T.apply(c) for c in corners])
        c = colours[i % len(colours)]
        for w in world[:4]:
            ax.plot(*np.array([T.t, w]).T, color=c, lw=0.8)
        ax.plot(*world.T, color=c, lw=0.8)
        # The line of sight, as far as the object.
        axis = T.rotate([0.0, 0.0, 1.0])
        reach = 0.45
        if frames.OBJECT in tree:
            reach = float(np.linalg.norm(frames.chain(tree.values(), frames.OBJECT).t - T.t))
        ax.plot(*np.array([T.t, T.t + reach * axis]).T, color=c, lw=0.6, ls=':')
        ax.text(*T.t, frame.removesuffix('_optical_frame'), color=c, fontsize=8)
    if frames.OBJECT in tree:
        o = frames.chain(tree.values(), frames.OBJECT).t
        ax.scatter(*o, color='k', s=30, label='object (tracked)')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.set_box_aspect((1.0, 0.8, 0.6))
    ax.set_title(title or f'the rig at t = {t:.1f} s (from /tf and /tf_static)')
    ax.view_init(elev=28, azim=-60)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
