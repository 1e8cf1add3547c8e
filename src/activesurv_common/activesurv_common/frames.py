"""The frame tree of the rig (REP 103/105 names), as (parent, child, transform) edges (pure core).

::

    world -> <cam>_base                  static: the rotation axis at linear position 0
    <cam>_base -> <cam>_platform         moving: linear stage along its axis, then the rotary stage
                                         (yaw_offset + yaw about z)
    <cam>_platform -> <cam>_optical_frame  static: the camera's offset from the rotation axis and
                                         its pitch (x right, y down, z forward)
    world -> overhead_optical_frame      static: the overhead camera
    world -> object                      moving: the tracked top marker (from the overhead fixes)

Composing the chain gives exactly :meth:`activesurv_common.mount.CameraMount.pose_from_joints`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount

WORLD = 'world'
OVERHEAD = 'overhead_optical_frame'
OBJECT = 'object'


class Edge(NamedTuple):
    parent: str
    child: str
    transform: Transform


def base_frame(camera_id: str) -> str:
    return f'{camera_id}_base'


def platform_frame(camera_id: str) -> str:
    return f'{camera_id}_platform'


def optical_frame(camera_id: str) -> str:
    """REP 103 optical frame of a camera (``overhead`` has ``overhead_optical_frame``)."""
    return f'{camera_id}_optical_frame'


def static_edges(mounts: Iterable[CameraMount], overhead: Transform | None = None) -> list[Edge]:
    """The edges that never move: each camera's base and optical frame, the overhead camera."""
    out = []
    for m in mounts:
        out.append(Edge(WORLD, base_frame(m.camera_id), Transform(np.eye(3), m.base)))
        out.append(
            Edge(
                platform_frame(m.camera_id),
                optical_frame(m.camera_id),
                Transform(m.R_platform_camera, m.offset),
            )
        )
    if overhead is not None:
        out.append(Edge(WORLD, OVERHEAD, overhead))
    return out


def joint_edge(mount: CameraMount, q: ArrayLike) -> Edge:
    """``<cam>_base -> <cam>_platform`` at joint positions ``q`` (stage order).

    Raises:
        CalibrationError: for the wrong number of joints or non-finite values.
    """
    # Checked as pose_from_joints checks them (the one rule); the edge is its platform part.
    linear, yaw = mount.stage_positions(q)
    axis = mount.linear_axis if mount.linear_axis is not None else np.zeros(3)
    return Edge(
        base_frame(mount.camera_id),
        platform_frame(mount.camera_id),
        Transform.about_z(mount.yaw_offset + yaw, linear * axis),
    )


def object_edge(xyz: Sequence[float]) -> Edge:
    """``world -> object`` at the tracked marker position."""
    return Edge(WORLD, OBJECT, Transform(np.eye(3), np.asarray(xyz, dtype=np.float64)))


def chain(edges: Iterable[Edge], frame: str, root: str = WORLD) -> Transform:
    """``T_root_frame`` by walking the edges from ``frame`` up to ``root``.

    Raises:
        KeyError: if ``frame`` does not reach ``root``.
    """
    parent_of = {e.child: e for e in edges}
    T = Transform.identity()
    f = frame
    while f != root:
        e = parent_of[f]
        T = e.transform.compose(T)
        f = e.parent
    return T
