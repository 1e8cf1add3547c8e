"""The commissioning boards as the renderer draws them (apart from
:mod:`activesurv_sim.board`, which a hardware file reads: that need not load the renderer and
its compiled kernels, 0.3 s of an orchestrator's start)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from activesurv_sim.board import BoardFixture
from activesurv_sim.render import Plate, Scene


def board_scene(fixture: BoardFixture, xy: ArrayLike) -> Scene:
    """Both boards of ``fixture`` with the carriage really at ``xy``."""
    x, y = (float(v) for v in np.asarray(xy, dtype=np.float64).reshape(-1)[:2])
    side, top = fixture.pose(x, y), fixture.top_pose(x, y)
    return Scene(
        (
            Plate.checkerboard(
                side.t, side.R[:, 2], side.R[:, 0], fixture.squares, fixture.square_size
            ),
            Plate.checkerboard(
                top.t, top.R[:, 2], top.R[:, 0], fixture.top_squares, fixture.top_square_size
            ),
        )
    )
