"""Commissioning views in simulation: the xy table carries a checkerboard, a camera looks.

The procedure is the one a lab runs (the graph's ``commission`` is to run it over topics): for
each station (stage positions aimed, with the nominal mount, at a point of the table), the table
first searches for the board along x until the camera finds it and centres it, then shows it at
three depths and three lateral offsets (the middle and either side of the frame: how the
board's image changes across the frame is what tells the principal point). Only the rendering
knows the rig's truth; the procedure itself works from nominal values and what the camera sees.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_imaging.calibration import board_points, find_corners
from activesurv_imaging.commissioning import BoardSighting, Station, order_like
from activesurv_imaging.response import BoardReader
from activesurv_sim.board import BoardFixture
from activesurv_sim.board_scene import board_scene
from activesurv_sim.optics import frame_optics
from activesurv_sim.render import Renderer, SensorNoise
from activesurv_sim.rig import Rig

Array = NDArray[np.float64]


def board_corners(fixture: BoardFixture) -> Array:
    """The side board's inner corners (N, 3) in its board frame."""
    return board_points(fixture.squares, fixture.square_size)


Look = Callable[[Array, float, float], Array | None]  # (joints, table x, y) -> corners


def plan_joints(mount: CameraMount, aim_x: float, aim_y: float, linear: float | None) -> Array:
    """Stage positions that point the (nominal) camera at world (aim_x, aim_y)."""
    q = np.array([0.0] if linear is None else [linear, 0.0])
    c = mount.pose_from_joints(q)
    bearing = math.atan2(aim_y - c.t[1], aim_x - c.t[0])
    axis = math.atan2(c.R[1, 2], c.R[0, 2])  # optical axis bearing at yaw 0
    q[-1] = math.remainder(bearing - axis, 2.0 * math.pi)
    return q


def collect_stations(
    look: Look,
    camera: CameraModel,
    mount: CameraMount,
    fixture: BoardFixture,
    linear_positions: tuple[float, ...] = (0.0, 0.15, 0.3),
    aims: tuple[float, ...] = (0.06, 0.136, 0.212, 0.288, 0.364, 0.44),
    depths: tuple[float, float, float] = (0.02, 0.10, 0.18),
    max_yaw: float = 0.9,
    laterals: tuple[float, ...] = (-0.012, 0.0, 0.012),
    limit: int | None = None,
) -> list[Station]:
    """The stations of one camera: search, centre, then nine board positions each.

    Args:
        look: shows the board with the carriage at (x, y) to the camera at joints; returns the
            corners it found or None.
        camera, mount: the nominal values (the procedure's only knowledge).
        fixture: the board on the carriage.
        laterals: the board's shifts along x about the centred place (m); +-12 mm puts it
            against either side of the frame at the middle depth.
        limit: at most this many stations, spread evenly over the candidates (a quick check
            of a rig; fewer views, larger uncertainties); None for all.
    """
    board = board_corners(fixture)
    stations = []
    mid = depths[1] + fixture.offset[1]
    linear = linear_positions if mount.linear_axis is not None else (None,)
    candidates = [plan_joints(mount, aim, mid, s) for s in linear for aim in aims]
    candidates = [q for q in candidates if abs(q[-1]) <= max_yaw]
    if limit is not None and limit < len(candidates):
        if limit < 1:
            raise ValueError(f'a camera needs at least one station, got {limit}')
        picked = np.unique(np.linspace(0, len(candidates) - 1, limit).round().astype(int))
        candidates = [candidates[i] for i in picked]
    for q in candidates:
        T = mount.pose_from_joints(q)
        d = T.R[:, 2]

        def on_axis(ty: float, T: Transform = T, d: Array = d) -> tuple[float, float]:
            lam = (ty + fixture.offset[1] - T.t[1]) / d[1]
            return float(T.t[0] + lam * d[0] - fixture.offset[0]), float(lam)

        x0, dist = on_axis(depths[1])
        shift = None
        for dx in (0.0, -0.015, 0.015, -0.03, 0.03, -0.045, 0.045):  # search
            if 0.0 <= x0 + dx <= 0.5:
                c = look(q, x0 + dx, depths[1])
                if c is not None:  # centre it (image x right is world +x here)
                    shift = dx - (float(c.mean(axis=0)[0]) - camera.cx) / camera.fx * dist
                    break
        if shift is None:
            continue
        sightings = []
        Tc = T.inverse()
        for ty in depths:
            xa = on_axis(ty)[0] + shift
            for lateral in laterals:
                tx = xa + lateral
                if not 0.0 <= tx <= 0.5:
                    continue
                c = look(q, tx, ty)
                if c is None:
                    continue
                Tb = fixture.pose(tx, ty)
                world = board @ Tb.R.T + Tb.t
                expected = camera.project(world @ Tc.R.T + Tc.t)
                sightings.append(BoardSighting(Tb, order_like(c, expected)))
        stations.append(Station(q, tuple(sightings)))
    return stations


def simulated_look(
    rig: Rig,
    camera_id: str,
    fixture: BoardFixture,
    seed: int = 0,
    reader: BoardReader | None = None,
) -> Look:
    """The rig's camera and table: where they really are, what the camera really sees
    (``reader``: finds the corners and keeps the edges, for the camera's response)."""
    read = reader or BoardReader(fixture.squares)
    rc = rig.camera(camera_id)
    true_mount = rc.true_mount()
    renderer = Renderer(rc.camera)
    noise = SensorNoise()
    rng = np.random.default_rng(seed)

    def look(q: Array, x: float, y: float) -> Array | None:
        scene = board_scene(fixture, np.array([x, y]) + rig.table_offset(x, y))
        T = true_mount.pose_from_joints(q)
        lens = frame_optics(rc.camera, rc.lens, T, scene.plates[0].center)  # at rest: no streak
        return read(renderer.render(T, scene, noise, rng, lens))

    return look


def simulated_overhead_look(
    rig: Rig, fixture: BoardFixture, seed: int = 0
) -> Callable[[float, float], Array | None]:
    """The rig's overhead camera looking at the top board with the carriage at (x, y)."""
    renderer = Renderer(rig.overhead)
    noise = SensorNoise()
    rng = np.random.default_rng(seed)

    def look(x: float, y: float) -> Array | None:
        scene = board_scene(fixture, np.array([x, y]) + rig.table_offset(x, y))
        T = rig.overhead_pose
        lens = frame_optics(rig.overhead, rig.overhead_lens, T, scene.plates[-1].center)
        image = renderer.render(T, scene, noise, rng, lens)
        return find_corners(image, fixture.top_squares)

    return look
