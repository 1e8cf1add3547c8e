"""Sensor descriptions: each dynamic camera's mount, stages, limits and intrinsics (YAML).

``config/paper_setup.yaml`` ships the paper's set-up (Fig. 4, Table I): four cameras that all
rotate about z; cam1 and cam4 also translate along world x on 300 mm linear stages. A motion
class (static, medium, fast) caps the stage velocities and accelerations (paper Section IV-A).
Joint order per camera: linear first (if any), then rotary; linear positions in m, rotary in rad.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from activesurv_common.camera_model import CameraModel, dynamic_camera
from activesurv_common.errors import CalibrationError
from activesurv_common.mount import CameraMount, mount_from_dict, mount_to_dict
from activesurv_common.occlusion import (
    PLATE_HALF_SIZE,
    Obstacle,
    ObstacleError,
    obstacles_from_list,
    obstacles_to_list,
)
from activesurv_common.yamlio import load_yaml
from activesurv_dispatch.errors import DispatchConfigError
from activesurv_stages.config import MotionClass, motion_class
from activesurv_stages.kinematics import AxisLimits

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Sensor:
    """One dynamic camera.

    Attributes:
        camera_id: ``cam1`` ...
        mount: where it sits and how its stages move it.
        camera: intrinsics.
        limits: per joint (mount.joint_names order): soft limits, and the motion class's caps.
        moves: False for a static system (its cameras keep their initial poses).
    """

    camera_id: str
    mount: CameraMount
    camera: CameraModel
    limits: tuple[AxisLimits, ...]
    moves: bool = True

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.mount.joint_names

    @property
    def has_linear(self) -> bool:
        return self.mount.linear_axis is not None

    def clamp(self, q: Array) -> Array:
        return np.array(
            [
                min(max(v, lim.min_position), lim.max_position)
                for v, lim in zip(q, self.limits, strict=True)
            ]
        )


def _sensor(entry: dict[str, Any], cls: MotionClass) -> Sensor:
    try:
        cid = str(entry['id'])
        mount_cfg = entry['mount']
        linear = entry.get('linear')
        rotary = entry['rotary']
        mount = mount_from_dict(
            cid, {**mount_cfg, 'linear_axis': linear['axis'] if linear else None}
        )
        limits = []
        if linear:
            v, a = cls.limits('linear')
            limits.append(
                AxisLimits(float(linear['min']), float(linear['max']), v or 1e-9, a or 1e-9)
            )
        v, a = cls.limits('rotary')
        limits.append(AxisLimits(float(rotary['min']), float(rotary['max']), v or 1e-9, a or 1e-9))
    except (KeyError, TypeError, ValueError) as exc:
        raise DispatchConfigError(f'camera entry {entry.get("id", "?")}: {exc!r}') from exc
    intr = entry.get('intrinsics')
    try:
        if isinstance(intr, dict):  # inline, camera_calibration layout
            camera = CameraModel.from_dict({'camera_name': cid, **intr})
        else:
            camera = CameraModel.load(intr) if intr else dynamic_camera(cid)
    except CalibrationError as exc:
        raise DispatchConfigError(f'camera entry {cid}: {exc}') from exc
    return Sensor(cid, mount, camera, tuple(limits), cls.moves)


@dataclass(frozen=True)
class Setup:
    """The camera system and the target geometry it is dispatched for."""

    sensors: tuple[Sensor, ...]
    initial: dict[str, Array]
    marker_radius: float
    motion: MotionClass
    obstacles: tuple[Obstacle, ...] = ()  # fixed solids of the cell (occlusion, eq. 1)
    object_half_size: float = PLATE_HALF_SIZE  # m: half side of an object's marker plates

    def sensor(self, camera_id: str) -> Sensor:
        for s in self.sensors:
            if s.camera_id == camera_id:
                return s
        raise DispatchConfigError(f'no camera {camera_id!r} in the set-up')

    def with_obstacles(self, obstacles: Sequence[Obstacle]) -> Setup:
        return replace(self, obstacles=tuple(obstacles))

    def with_initial(self, initial: dict[str, Array]) -> Setup:
        return replace(self, initial={k: np.asarray(v, dtype=float) for k, v in initial.items()})

    def calibrated(
        self, mounts: Mapping[str, CameraMount], cameras: Mapping[str, CameraModel]
    ) -> Setup:
        """The same stages with the mounts and intrinsics of a calibration.

        Raises:
            DispatchConfigError: if the calibration lacks a camera of the set-up.
        """
        missing = [s.camera_id for s in self.sensors if s.camera_id not in mounts]
        missing += [s.camera_id for s in self.sensors if s.camera_id not in cameras]
        if missing:
            raise DispatchConfigError(f'the calibration has no {sorted(set(missing))}')
        sensors = []
        for s in self.sensors:
            m = mounts[s.camera_id]
            if (m.linear_axis is None) != (s.mount.linear_axis is None):
                raise DispatchConfigError(
                    f'{s.camera_id}: the calibration and the set-up disagree on a linear stage'
                )
            mount = replace(
                m, linear_joint=s.mount.linear_joint, rotary_joint=s.mount.rotary_joint
            )
            sensors.append(replace(s, mount=mount, camera=cameras[s.camera_id]))
        return replace(self, sensors=tuple(sensors))


def setup_to_dict(setup: Setup) -> dict[str, Any]:
    """A set-up as :func:`setup_from_dict` reads it (mounts and intrinsics inline)."""
    cameras = []
    for s in setup.sensors:
        mount = mount_to_dict(s.mount)
        axis = mount.pop('linear_axis')
        entry: dict[str, Any] = {'id': s.camera_id, 'mount': mount}
        rotary = s.limits[-1]
        if s.has_linear:
            lin = s.limits[0]
            entry['linear'] = {
                'axis': axis,
                'min': float(lin.min_position),
                'max': float(lin.max_position),
            }
        entry['rotary'] = {'min': float(rotary.min_position), 'max': float(rotary.max_position)}
        entry['initial'] = [float(v) for v in setup.initial[s.camera_id]]
        entry['intrinsics'] = s.camera.to_dict()
        cameras.append(entry)
    return {
        'marker_radius': float(setup.marker_radius),
        'cameras': cameras,
        'obstacles': obstacles_to_list(setup.obstacles),
    }


def setup_from_dict(data: dict[str, Any], motion: str = 'fast') -> Setup:
    """Parse a set-up; ``motion`` picks the motion class that caps the stages.

    Raises:
        DispatchConfigError: naming what is wrong.
    """
    if not isinstance(data, dict) or 'cameras' not in data:
        raise DispatchConfigError('a set-up needs a "cameras" list')
    cls = motion_class(motion)
    sensors = tuple(_sensor(e, cls) for e in data['cameras'])
    ids = [s.camera_id for s in sensors]
    if len(set(ids)) != len(ids):
        raise DispatchConfigError(f'duplicate camera ids {ids}')
    initial = {}
    for s, e in zip(sensors, data['cameras'], strict=True):
        q = np.array(e.get('initial', [0.0] * len(s.joint_names)), dtype=float)
        if q.shape != (len(s.joint_names),) or not np.all(np.isfinite(q)):
            raise DispatchConfigError(f'{s.camera_id}: initial needs {len(s.joint_names)} numbers')
        for v, lim in zip(q, s.limits, strict=True):
            lim.check_position(float(v), f'{s.camera_id} initial position')
        initial[s.camera_id] = q
    radius = float(data.get('marker_radius', 0.0125))
    if not (math.isfinite(radius) and radius > 0):
        raise DispatchConfigError('marker_radius must be > 0')
    try:
        obstacles = obstacles_from_list(data.get('obstacles'))
    except ObstacleError as exc:
        raise DispatchConfigError(str(exc)) from exc
    return Setup(sensors, initial, radius, cls, obstacles)


def default_setup_path() -> Path:
    """The paper's set-up, shipped in the package's config directory."""
    here = Path(__file__).resolve().parent
    for candidate in (
        here.parent / 'config' / 'paper_setup.yaml',
        here / 'data' / 'paper_setup.yaml',
    ):
        if candidate.exists():
            return candidate
    try:
        # optional: only a colcon install has an ament index
        from ament_index_python.packages import get_package_share_directory

        return (
            Path(get_package_share_directory('activesurv_dispatch'))
            / 'config'
            / 'paper_setup.yaml'
        )
    except (ImportError, LookupError, OSError) as exc:
        raise DispatchConfigError('cannot find config/paper_setup.yaml') from exc


def load_setup(path: Path | str | None = None, motion: str = 'fast') -> Setup:
    p = default_setup_path() if path is None else Path(path)
    try:
        data = load_yaml(p.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise DispatchConfigError(f'cannot read set-up {p}: {exc}') from exc
    return setup_from_dict(data, motion)
