"""What an imager draws over its image for a demand (pure core): the fitted ellipse, its
centre, the chosen marker normal, or, when the detection failed, its status and reason.

Shapes are in image pixels (x right, y down); ``conversions.annotation_markers`` turns them
into ``visualization_msgs/ImageMarker`` messages on ``<camera>/marker_annotations``, which
Foxglove and RViz draw over the image of the same stamp and frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.observation import Observation

Array = NDArray[np.float64]
Projector = Callable[[Array], Array]  # camera-frame points (N, 3) -> pixels (N, 2)


@dataclass(frozen=True)
class Shape:
    """One annotation: ``kind`` is ``ellipse`` (closed polyline), ``centre`` (a circle of
    ``size`` px), ``normal`` (a line) or ``status`` (a failure: a circle at ``points[0]``
    and the ``label``)."""

    kind: str
    points: tuple[tuple[float, float], ...]
    ok: bool = True
    size: float = 0.0
    label: str = ''


def ellipse_points(center: Array, semi_axes: Array, angle: float, n: int = 48) -> Array:
    """``n + 1`` points around an ellipse (closed: the last is the first)."""
    t = np.linspace(0.0, 2.0 * math.pi, n + 1)
    a, b = float(semi_axes[0]), float(semi_axes[1])
    c, s = math.cos(angle), math.sin(angle)
    x, y = a * np.cos(t), b * np.sin(t)
    out: Array = np.column_stack([center[0] + c * x - s * y, center[1] + s * x + c * y])
    return out


def annotation_shapes(
    obs: Observation,
    project: Projector | None = None,
    normal_length: float = 0.02,
    image_size: tuple[int, int] = (640, 480),
) -> list[Shape]:
    """The shapes of one observation.

    Args:
        obs: the imager's observation.
        project: the camera's projection (for the normal); None: no normal is drawn.
        normal_length: length of the drawn normal in the world (m).
        image_size: (width, height) px, where a failure's marker goes (the centre).
    """
    if obs.status is not ObservationStatus.OK or obs.ellipse is None:
        w, h = image_size
        label = f'{obs.status.name.lower()}: {obs.reason}' if obs.reason else obs.status.name
        where = (
            (float(obs.ellipse.center[0]), float(obs.ellipse.center[1]))
            if obs.ellipse is not None
            else (w / 2.0, h / 2.0)
        )
        return [Shape('status', (where,), ok=False, size=20.0, label=label)]
    e = obs.ellipse
    centre = np.asarray(e.center, dtype=np.float64)
    shapes = [
        Shape(
            'ellipse',
            tuple(
                (float(x), float(y))
                for x, y in ellipse_points(centre, np.asarray(e.semi_axes), e.angle)
            ),
        ),
        Shape('centre', ((float(centre[0]), float(centre[1])),), size=3.0),
    ]
    if (
        project is not None
        and obs.position is not None
        and obs.normal is not None
        and obs.camera_pose is not None
    ):
        T = obs.camera_pose.inverse()
        ends = np.array(
            [T.apply(obs.position), T.apply(obs.position + normal_length * obs.normal)]
        )
        if np.all(ends[:, 2] > 1e-6):
            px = project(ends)
            if np.all(np.isfinite(px)):
                shapes.append(Shape('normal', tuple((float(x), float(y)) for x, y in px)))
    return shapes
