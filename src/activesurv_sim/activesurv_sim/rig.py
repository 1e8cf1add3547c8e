"""The rig: the simulated world's true hardware, apart from what the system believes.

A rig file holds, per dynamic camera, its true intrinsics (ROS ``camera_calibration`` layout)
and mount, and how accurately its stages really reach a commanded position; the same for the
overhead camera (intrinsics and pose) and the xy table. Only the simulator reads it: the
renderer draws with the rig's camera, puts the camera where the rig's mount and the stages'
position errors put it, and the xy table carries the object with its own position error. Every
other node works from a calibration (``activesurv commission``) or from nominal values.

Layout (SI units, world frame; the keys of :func:`rig_to_dict`)::

    rig: {name: nominal, seed: null}
    cameras:
      cam1:
        camera_info: {image_width, image_height, camera_matrix, distortion_model, ...}
        mount: {base: [x, y, z], yaw_offset, pitch, rotation_centre_offset: [x, y, z],
                linear_axis: [1, 0, 0] or null}
        stage_accuracy: {linear: 3.0e-05, rotary: 4.85e-05, seed: 1}
    overhead:
      camera_info: {...}
      pose: [x, y, z, qx, qy, qz, qw]       # T_world_overhead_optical_frame
    xy_table: {accuracy: [4.8e-05, 2.4e-05], seed: 0}
    obstacles: []                           # boxes and cylinders in the cell (occlusion)

Stage accuracy (Table I: linear 30 um, rotary 10 arcsec, xy table 48 / 24 um) is the largest
error of where an axis really is against where it reports: a repeatable, seeded function of the
position (a lead screw's periodic error and slow run-out), as a real stage's error map is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from activesurv_common.calibration import Calibration, pose_from_list, pose_to_list
from activesurv_common.camera_model import CameraModel, dynamic_camera, overhead_camera
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, rot_x, rot_y, rot_z
from activesurv_common.mount import CameraMount, mount_from_dict, mount_to_dict
from activesurv_common.occlusion import Obstacle, obstacles_from_list, obstacles_to_list
from activesurv_sim.errors import SimError
from activesurv_sim.optics import OVERHEAD_FOCAL_LENGTH, Optics, OpticsError, focus_for
from activesurv_sim.rig_schema import rig_problems

Array = NDArray[np.float64]

LINEAR_ACCURACY = 30e-6  # m, Table I
ROTARY_ACCURACY = math.radians(10.0 / 3600.0)  # 10 arcsec, Table I
TABLE_ACCURACY = (48e-6, 24e-6)  # m (x, y), Table I


@dataclass(frozen=True)
class Perturbation:
    """How far ``activesurv rig perturb`` moves each value (uniform within these bounds)."""

    focal_length: float = 0.02  # relative
    principal_point: float = 15.0  # px
    k1: float = 0.1
    base: float = 3e-3  # m, per axis
    angle: float = math.radians(1.0)  # yaw, pitch (and the overhead camera's roll)
    offset_min: float = 5e-3  # m: the optical centre's horizontal distance from the axis
    offset_max: float = 30e-3


PERTURBATION = Perturbation()


class RigError(SimError, ValueError):
    """A rig file is malformed or cannot be read or written."""


@dataclass(frozen=True)
class AxisError:
    """Where an axis really is against where it reports, as a repeatable function of position.

    ``error(q) = accuracy * sum_i w_i sin(2 pi q / period_i + phase_i)`` with ``sum |w_i| = 1``:
    never more than ``accuracy``, and the same at the same position, as a stage's error map.

    Attributes:
        accuracy: the largest error (m or rad); 0 for an ideal axis.
        periods: periods of the error terms (m or rad).
        seed: draws the weights and phases.
    """

    accuracy: float
    periods: tuple[float, ...]
    seed: int = 0
    _w: Array = field(init=False, repr=False, compare=False)
    _phase: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.accuracy) and self.accuracy >= 0.0):
            raise RigError(f'stage accuracy must be finite and >= 0, got {self.accuracy}')
        if not self.periods or not all(p > 0.0 and math.isfinite(p) for p in self.periods):
            raise RigError(f'error periods must be > 0, got {self.periods}')
        rng = np.random.default_rng([int(self.seed) & 0xFFFFFFFF, len(self.periods)])
        w = rng.uniform(0.3, 1.0, len(self.periods)) * rng.choice([-1.0, 1.0], len(self.periods))
        object.__setattr__(self, '_w', w / np.sum(np.abs(w)))
        object.__setattr__(self, '_phase', rng.uniform(0.0, 2.0 * math.pi, len(self.periods)))

    def error(self, q: float) -> float:
        if self.accuracy == 0.0:
            return 0.0
        arg = 2.0 * math.pi * q / np.asarray(self.periods) + self._phase
        return float(self.accuracy * np.dot(self._w, np.sin(arg)))


@lru_cache(maxsize=256)
def linear_error(accuracy: float, seed: int) -> AxisError:
    """A lead-screw axis: 2 mm pitch error and slower run-out over the 300 mm travel (made
    once per accuracy and seed: the table's state asks for it at every tick)."""
    return AxisError(accuracy, (2e-3, 37e-3, 0.6), seed)


@lru_cache(maxsize=256)
def rotary_error(accuracy: float, seed: int) -> AxisError:
    """A worm-gear rotary axis: once and four times per turn, and per worm tooth (90)."""
    return AxisError(accuracy, (2.0 * math.pi, math.pi / 2.0, 2.0 * math.pi / 90.0), seed)


@dataclass(frozen=True)
class TrueMount(CameraMount):
    """A camera mount whose stages are not quite where they report (the simulator's truth)."""

    linear_error: AxisError | None = None
    rotary_error: AxisError | None = None

    def camera_pose(self, linear: float, yaw: float) -> Transform:
        if self.linear_error is not None and self.linear_axis is not None:
            linear += self.linear_error.error(linear)
        if self.rotary_error is not None:
            yaw += self.rotary_error.error(yaw)
        return super().camera_pose(linear, yaw)


@dataclass(frozen=True)
class RigCamera:
    """One dynamic camera of the rig: what it really is and where it really sits."""

    camera: CameraModel
    mount: CameraMount
    linear_accuracy: float = LINEAR_ACCURACY
    rotary_accuracy: float = ROTARY_ACCURACY
    error_seed: int = 0
    optics: Optics | None = None  # None: the paper's, focused at the table's middle

    @property
    def lens(self) -> Optics:
        """Its optics (the default focused from where its mount stands)."""
        return self.optics if self.optics is not None else focus_for(self.mount.base)

    def true_mount(self) -> TrueMount:
        m = self.mount
        lin = (
            linear_error(self.linear_accuracy, self.error_seed * 2)
            if m.linear_axis is not None
            else None
        )
        rot = rotary_error(self.rotary_accuracy, self.error_seed * 2 + 1)
        return TrueMount(
            m.camera_id,
            m.base,
            m.yaw_offset,
            m.pitch,
            m.offset,
            m.linear_axis,
            m.linear_joint,
            m.rotary_joint,
            linear_error=lin,
            rotary_error=rot,
        )


@dataclass(frozen=True)
class Rig:
    """The simulated world's hardware.

    Attributes:
        name: a label (``nominal``, ``perturbed-7``).
        cameras: dynamic cameras by id.
        overhead: the overhead camera's intrinsics.
        overhead_pose: ``T_world_overhead_optical_frame``.
        table_accuracy: the xy table's largest position errors (x, y) in m.
        table_seed: draws the table's error map.
        seed: the perturbation seed (None for the nominal rig).
        obstacles: fixed solids of the cell (world frame): the simulated cameras see them and
            the system is told of them (:mod:`activesurv_common.occlusion`).
    """

    name: str
    cameras: dict[str, RigCamera]
    overhead: CameraModel
    overhead_pose: Transform
    table_accuracy: tuple[float, float] = TABLE_ACCURACY
    table_seed: int = 0
    seed: int | None = None
    obstacles: tuple[Obstacle, ...] = ()
    overhead_optics: Optics | None = None  # None: the paper's 12 mm lens, focused on the table

    @property
    def overhead_lens(self) -> Optics:
        """The overhead camera's optics."""
        if self.overhead_optics is not None:
            return self.overhead_optics
        return focus_for(self.overhead_pose.t, OVERHEAD_FOCAL_LENGTH)

    def camera(self, camera_id: str) -> RigCamera:
        try:
            return self.cameras[camera_id]
        except KeyError:
            raise RigError(
                f'the rig has no camera {camera_id!r}; it has {sorted(self.cameras)}'
            ) from None

    def table_errors(self) -> tuple[AxisError, AxisError]:
        """The xy table's x and y error maps (lead screws)."""
        return (
            linear_error(self.table_accuracy[0], self.table_seed * 2 + 1001),
            linear_error(self.table_accuracy[1], self.table_seed * 2 + 1002),
        )

    def truth(self) -> Calibration:
        """The rig as a calibration: what a perfect commissioning would find (the cameras'
        response and exposure time included)."""
        return Calibration(
            f'truth of {self.name}',
            {
                c: replace(
                    rc.camera,
                    gamma=rc.lens.gamma,
                    exposure_time=rc.lens.exposure_time,
                    f_number=rc.lens.f_number,
                    focus_distance=rc.lens.focus_distance,
                    focal_length=rc.lens.focal_length,
                )
                for c, rc in self.cameras.items()
            },
            {c: rc.mount for c, rc in self.cameras.items()},
            self.overhead,
            self.overhead_pose,
        )

    def table_offset(self, x: float, y: float) -> Array:
        """Where the table really is minus where it is commanded (m, world xy)."""
        ex, ey = self.table_errors()
        return np.array([ex.error(x), ey.error(y)])


# -- nominal and perturbed rigs ---------------------------------------------------------------


def nominal_rig(mounts: Mapping[str, CameraMount], overhead_pose: ArrayLike) -> Rig:
    """The paper's rig: Table I optics, the set-up's mounts (axis through the optical centre).

    Args:
        mounts: the dynamic cameras' nominal mounts by id (``paper_setup.yaml``).
        overhead_pose: ``[x, y, z, qx, qy, qz, qw]`` of the overhead camera.
    """
    cameras = {
        cid: RigCamera(dynamic_camera(cid), m, error_seed=i + 1)
        for i, (cid, m) in enumerate(mounts.items())
    }
    pose = pose_from_list(overhead_pose, 'overhead pose')
    return Rig('nominal', cameras, overhead_camera(), pose)


def _perturb_camera(model: CameraModel, rng: np.random.Generator, p: Perturbation) -> CameraModel:
    K = model.K.copy()
    scale = 1.0 + rng.uniform(-p.focal_length, p.focal_length)
    K[0, 0] *= scale
    K[1, 1] *= scale * (1.0 + rng.uniform(-1e-3, 1e-3))  # pixels are nearly square
    K[0, 2] += rng.uniform(-p.principal_point, p.principal_point)
    K[1, 2] += rng.uniform(-p.principal_point, p.principal_point)
    dist = model.dist.copy()
    dist[0] += rng.uniform(-p.k1, p.k1)
    return CameraModel(model.width, model.height, K, dist, model.name)


def perturb_rig(rig: Rig, seed: int, p: Perturbation = PERTURBATION) -> Rig:
    """A realistic rig near ``rig``: each value drawn uniformly within :data:`PERTURBATION`.

    Focal length +-2 %, principal point +-15 px, k1 +-0.1; mount base +-3 mm per axis, yaw and
    pitch +-1 deg; the optical centre 5-30 mm off the rotary axis (horizontal, any direction);
    the overhead camera's optics alike and its pose +-3 mm, +-1 deg; new stage and table error
    maps.
    """
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 16])
    cameras = {}
    for i, (cid, rc) in enumerate(sorted(rig.cameras.items())):
        m = rc.mount
        radius = rng.uniform(p.offset_min, p.offset_max)
        bearing = rng.uniform(0.0, 2.0 * math.pi)
        mount = CameraMount(
            cid,
            m.base + rng.uniform(-p.base, p.base, 3),
            m.yaw_offset + rng.uniform(-p.angle, p.angle),
            m.pitch + rng.uniform(-p.angle, p.angle),
            m.offset + radius * np.array([math.cos(bearing), math.sin(bearing), 0.0]),
            m.linear_axis,
            m.linear_joint,
            m.rotary_joint,
        )
        camera = _perturb_camera(rc.camera, rng, p)
        cameras[cid] = replace(rc, camera=camera, mount=mount, error_seed=seed * 16 + i + 1)
    tilt = rot_z(rng.uniform(-p.angle, p.angle)) @ rot_y(rng.uniform(-p.angle, p.angle))
    tilt = tilt @ rot_x(rng.uniform(-p.angle, p.angle))
    pose = Transform(
        tilt @ rig.overhead_pose.R, rig.overhead_pose.t + rng.uniform(-p.base, p.base, 3)
    )
    return Rig(
        f'perturbed-{seed}',
        cameras,
        _perturb_camera(rig.overhead, rng, p),
        pose,
        rig.table_accuracy,
        int(seed),
        int(seed),
        rig.obstacles,
    )


# -- files ------------------------------------------------------------------------------------


def rig_to_dict(rig: Rig) -> dict[str, Any]:
    cams: dict[str, Any] = {}
    for cid, rc in rig.cameras.items():
        cams[cid] = {
            'camera_info': rc.camera.to_dict(),
            'optics': rc.lens.to_dict(),
            'mount': mount_to_dict(rc.mount),
            'stage_accuracy': {
                'linear': float(rc.linear_accuracy),
                'rotary': float(rc.rotary_accuracy),
                'seed': int(rc.error_seed),
            },
        }
    return {
        'rig': {'name': rig.name, 'seed': rig.seed},
        'cameras': cams,
        'overhead': {
            'camera_info': rig.overhead.to_dict(),
            'optics': rig.overhead_lens.to_dict(),
            'pose': pose_to_list(rig.overhead_pose),
        },
        'xy_table': {
            'accuracy': [float(v) for v in rig.table_accuracy],
            'seed': int(rig.table_seed),
        },
        'obstacles': obstacles_to_list(rig.obstacles),
    }


def _positive(value: Any, what: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise RigError(f'{what} must be finite and >= 0, got {value!r}')
    return v


def rig_from_dict(data: Any, defaults: Mapping[str, CameraMount] | None = None) -> Rig:
    """Read a rig mapping; a mount key left out is taken from ``defaults`` (the set-up).

    Raises:
        RigError: naming what is missing or malformed.
    """
    found = rig_problems(dict(data) if isinstance(data, Mapping) else data)
    if found:
        raise RigError('; '.join(found))
    cameras: dict[str, RigCamera] = {}
    try:
        for cid, entry in data['cameras'].items():
            cid = str(cid)
            if not isinstance(entry, Mapping):
                raise RigError(f'{cid}: expected a mapping, got {entry!r}')
            info = dict(entry.get('camera_info') or dynamic_camera(cid).to_dict())
            info.setdefault('camera_name', cid)
            mount_data = dict(entry.get('mount') or {})
            if defaults is not None and cid in defaults:
                base = mount_to_dict(defaults[cid])
                if 'offset' in mount_data:
                    base.pop('rotation_centre_offset')
                mount_data = {**base, **mount_data}
            nominal = defaults.get(cid) if defaults is not None else None
            mount = mount_from_dict(cid, mount_data)
            if nominal is not None:  # joint names come with the set-up's stages
                mount = replace(
                    mount, linear_joint=nominal.linear_joint, rotary_joint=nominal.rotary_joint
                )
            acc = dict(entry.get('stage_accuracy') or {})
            cameras[cid] = RigCamera(
                CameraModel.from_dict(info),
                mount,
                _positive(acc.get('linear', LINEAR_ACCURACY), f'{cid} linear accuracy'),
                _positive(acc.get('rotary', ROTARY_ACCURACY), f'{cid} rotary accuracy'),
                int(acc.get('seed', len(cameras) + 1)),
                _optics(entry.get('optics'), focus_for(mount.base), cid),
            )
        over = dict(data.get('overhead') or {})
        overhead = CameraModel.from_dict(
            {'camera_name': 'overhead', **(over.get('camera_info') or overhead_camera().to_dict())}
        )
        if 'pose' not in over:
            raise RigError('the rig needs overhead.pose [x, y, z, qx, qy, qz, qw]')
        table = dict(data.get('xy_table') or {})
        acc_xy = table.get('accuracy', list(TABLE_ACCURACY))
        if len(acc_xy) != 2:
            raise RigError(f'xy_table.accuracy needs [x, y], got {acc_xy!r}')
        meta = dict(data.get('rig') or {})
        seed = meta.get('seed')
        pose = pose_from_list(over['pose'], 'overhead.pose')
        over_optics = _optics(
            over.get('optics'), focus_for(pose.t, OVERHEAD_FOCAL_LENGTH), 'overhead'
        )
        return Rig(
            str(meta.get('name', 'rig')),
            cameras,
            overhead,
            pose_from_list(over['pose'], 'overhead.pose'),
            (_positive(acc_xy[0], 'xy table accuracy'), _positive(acc_xy[1], 'xy accuracy')),
            int(table.get('seed', 0)),
            None if seed is None else int(seed),
            obstacles_from_list(data.get('obstacles')),
            over_optics,
        )
    except (CalibrationError, TypeError, ValueError) as exc:
        if isinstance(exc, RigError):
            raise
        raise RigError(f'malformed rig: {exc}') from exc


def _optics(data: Any, default: Optics, where: str) -> Optics:
    """A camera's ``optics`` section over its default.

    Raises:
        RigError: for a value out of range.
    """
    try:
        return Optics.from_dict(dict(data) if data else None, default)
    except OpticsError as exc:
        raise RigError(f'{where}: {exc}') from exc


def save_rig(rig: Rig, path: Path) -> None:
    try:
        path.write_text(
            '# activesurv rig: the simulated hardware as it really is (SI units, world frame)\n'
            + yaml.safe_dump(rig_to_dict(rig), sort_keys=False)
        )
    except OSError as exc:
        raise RigError(f'cannot write rig {path}: {exc}') from exc


def load_rig(path: Path | str, defaults: Mapping[str, CameraMount] | None = None) -> Rig:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise RigError(f'cannot read rig {path}: {exc}') from exc
    try:
        return rig_from_dict(data, defaults)
    except RigError as exc:
        raise RigError(f'{path}: {exc}') from exc
