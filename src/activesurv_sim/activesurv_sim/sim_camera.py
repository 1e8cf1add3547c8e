"""Core of the simulated camera: render the object as it was at a given instant.

Object states (top marker, side marker, side normal) and stage joint states arrive as
time-stamped samples; a frame for instant t uses both interpolated to t, so a triggered capture
at a demand instant sees exactly the scene at that instant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, unit
from activesurv_common.mount import CameraMount
from activesurv_common.timeseries import TimeSeries
from activesurv_sim.errors import RenderError
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise


@dataclass(frozen=True)
class ObjectGeometry:
    """The object's two markers as the cameras see them.

    Attributes:
        side_radius: radius of the side marker, the surveyed target (m).
        top_radius: radius of the top marker, tracked by the overhead camera (m).
        plate_half_size: half side of the black plates carrying the markers (m).
    """

    side_radius: float = 0.0125
    top_radius: float = 0.0125
    plate_half_size: float = 0.03


def object_scene(state: ArrayLike, geometry: ObjectGeometry) -> Scene:
    """Plates of the object from a 9-vector (top xyz, side xyz, side normal xyz)."""
    s = np.asarray(state, dtype=np.float64).reshape(9)
    side_n = unit(s[6:9], 'side normal')
    horizontal = np.cross([0.0, 0.0, 1.0], side_n)
    if np.linalg.norm(horizontal) < 1e-6:
        horizontal = np.array([1.0, 0.0, 0.0])
    return Scene(
        (
            Plate.disc(s[3:6], side_n, geometry.side_radius, geometry.plate_half_size, horizontal),
            Plate.disc(s[0:3], [0.0, 0.0, 1.0], geometry.top_radius, geometry.plate_half_size),
        )
    )


class SimulatedCamera:
    """Renders frames of the object for one camera on its (possibly moving) mount."""

    def __init__(
        self,
        camera: CameraModel,
        mount: CameraMount | Transform,
        geometry: ObjectGeometry | None = None,
        noise: SensorNoise | None = None,
        seed: int = 0,
    ) -> None:
        self.camera = camera
        self.renderer = Renderer(camera)
        self.mount = mount
        self.geometry = ObjectGeometry() if geometry is None else geometry
        self.noise = SensorNoise() if noise is None else noise
        self.rng = np.random.default_rng(seed)
        self.objects = TimeSeries(9)
        n_joints = len(mount.joint_names) if isinstance(mount, CameraMount) else 0
        self.joints = TimeSeries(max(n_joints, 1))

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.mount.joint_names if isinstance(self.mount, CameraMount) else ()

    def camera_pose(self, t: float, hold: float = 0.2) -> Transform:
        """The camera pose at ``t``.

        Raises:
            RenderError: if the stage state at ``t`` is unknown.
        """
        if not isinstance(self.mount, CameraMount):
            return self.mount
        q = self.joints.at(t, hold)
        if q is None:
            raise RenderError(f'no stage state near t={t:.3f} s')
        return self.mount.pose_from_joints(q)

    def render_at(self, t: float, hold: float = 0.2) -> NDArray[np.uint8]:
        """The frame exposed at ``t``.

        Raises:
            RenderError: if the object or stage state at ``t`` is unknown.
        """
        state = self.objects.at(t, hold)
        if state is None:
            raise RenderError(f'no object state near t={t:.3f} s')
        return self.renderer.render(
            self.camera_pose(t, hold), object_scene(state, self.geometry), self.noise, self.rng
        )
