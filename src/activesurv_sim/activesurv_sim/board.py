"""The commissioning target: checkerboards on the xy table's carriage.

A side board faces the dynamic cameras (-y), where the object's side marker would be; a larger
top board faces up for the overhead camera, at the top marker's height. Board frames follow
OpenCV (:mod:`activesurv_imaging.calibration`): origin at the board centre, x along the
columns (world +x here), z away from the side the cameras see.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activesurv_common.geometry import Transform

_SIDE = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # z = +y (away)
_TOP = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # z = -z (down)


@dataclass(frozen=True)
class BoardFixture:
    """Where the boards sit relative to the carriage position (x, y) (m).

    Attributes:
        squares, square_size: the side board (columns, rows; m).
        offset: the side board's centre minus the carriage position.
        top_squares, top_square_size: the top board.
        top_height: the top board's plane (z, m).
    """

    squares: tuple[int, int] = (9, 7)
    square_size: float = 0.004
    offset: tuple[float, float, float] = (0.0, -0.03, 0.05)
    top_squares: tuple[int, int] = (9, 7)
    top_square_size: float = 0.012
    top_height: float = 0.08

    def pose(self, x: float, y: float) -> Transform:
        """``T_world_board`` of the side board with the carriage at (x, y)."""
        return Transform(_SIDE, np.array([x, y, 0.0]) + np.asarray(self.offset))

    def top_pose(self, x: float, y: float) -> Transform:
        """``T_world_board`` of the top board with the carriage at (x, y)."""
        return Transform(_TOP, np.array([x, y, self.top_height]))
