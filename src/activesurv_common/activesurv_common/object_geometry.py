"""The surveyed object, once: where its two markers sit on the carriage and how big they are.

The paper's object (Fig. 5, Table I) rides on the xy table: a top marker, tracked by the overhead
camera, at ``top_height`` above the table; a side marker, the target the mobile cameras survey,
at ``side_offset`` from the top marker's centre and facing ``side_normal``; both white discs on
square black plates. The object frame has the world's axes (the table translates it only).
The simulator renders it, the xy table reports it, the hardware file describes the one a lab
built, and the predictor maps a tracked top marker to a demanded side marker with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from activesurv_common.errors import GeometryError
from activesurv_common.occlusion import PLATE_HALF_SIZE

Vector3 = tuple[float, float, float]


@dataclass(frozen=True)
class ObjectGeometry:
    """The object's markers (m; the normal is a direction).

    Attributes:
        top_height: height of the top marker's plane above the table's reference (m).
        side_offset: side-marker centre minus top-marker centre (m).
        side_normal: normal of the side marker (normalised by :attr:`normal`).
        side_radius: radius of the side marker (Table I: 25 mm diameter).
        top_radius: radius of the top marker.
        plate_half_size: half side of the black plates carrying the markers.

    Raises:
        GeometryError: for a value that is not finite, a zero normal or a radius or plate
            that is not positive.
    """

    top_height: float = 0.08
    side_offset: Vector3 = (0.0, -0.03, -0.03)
    side_normal: Vector3 = (0.0, -1.0, 0.0)
    side_radius: float = 0.0125
    top_radius: float = 0.0125
    plate_half_size: float = PLATE_HALF_SIZE

    def __post_init__(self) -> None:
        values = (self.top_height, *self.side_offset, *self.side_normal)
        if len(self.side_offset) != 3 or len(self.side_normal) != 3:
            raise GeometryError('side_offset and side_normal need 3 numbers each')
        if not all(math.isfinite(float(v)) for v in values):
            raise GeometryError('object geometry values must be finite')
        if math.hypot(*self.side_normal) < 1e-9:
            raise GeometryError('the side marker needs a non-zero normal')
        sizes = (self.side_radius, self.top_radius, self.plate_half_size)
        if not all(math.isfinite(v) and v > 0.0 for v in sizes):
            raise GeometryError('marker radii and the plate size must be positive (m)')

    @property
    def offset(self) -> NDArray[np.float64]:
        """Side-marker centre minus top-marker centre (m)."""
        return np.asarray(self.side_offset, dtype=np.float64)

    @property
    def normal(self) -> NDArray[np.float64]:
        """The side marker's unit normal."""
        n = np.asarray(self.side_normal, dtype=np.float64)
        return n / float(np.linalg.norm(n))
