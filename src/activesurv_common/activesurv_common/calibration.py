"""What the system believes about its hardware: a calibration directory.

``activesurv commission`` writes one; every node but the simulator's works from one (or from
the nominal values). Layout::

    CALDIR/<camera>.yaml          intrinsics, ROS camera_calibration layout (camera_info_manager)
    CALDIR/<camera>_mount.yaml    {camera_id, mount: {base, yaw_offset, pitch,
                                   rotation_centre_offset, linear_axis}} (SI units, world frame)
    CALDIR/overhead.yaml          the overhead camera's intrinsics
    CALDIR/overhead_pose.yaml     {pose: [x, y, z, qx, qy, qz, qw]}: T_world_overhead_optical_frame
    CALDIR/commission.json        how well each was estimated (commissioning's report)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike

from activesurv_common.camera_model import CameraModel
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform, matrix_from_quaternion, quaternion_from_matrix
from activesurv_common.mount import CameraMount, mount_from_dict, mount_to_dict
from activesurv_common.yamlio import load_yaml

OVERHEAD = 'overhead'


def pose_to_list(T: Transform) -> list[float]:
    """``[x, y, z, qx, qy, qz, qw]`` of a transform."""
    return [float(v) for v in T.t] + [float(v) for v in quaternion_from_matrix(T.R)]


def pose_from_list(values: ArrayLike, what: str = 'pose') -> Transform:
    """A transform from ``[x, y, z, qx, qy, qz, qw]``.

    Raises:
        CalibrationError: unless seven finite numbers.
    """
    p = np.asarray(values, dtype=np.float64).reshape(-1)
    if p.shape != (7,) or not np.all(np.isfinite(p)):
        raise CalibrationError(f'{what} needs 7 finite numbers [x, y, z, qx, qy, qz, qw]')
    return Transform.from_rt(matrix_from_quaternion(p[3:]), p[:3])


@dataclass(frozen=True)
class Calibration:
    """Intrinsics and mounts of every dynamic camera, and the overhead camera's.

    Attributes:
        name: where it came from (``nominal``, ``truth``, a directory).
        cameras: intrinsics by camera id.
        mounts: mounts by camera id.
        overhead: the overhead camera's intrinsics.
        overhead_pose: ``T_world_overhead_optical_frame``.
    """

    name: str
    cameras: Mapping[str, CameraModel]
    mounts: Mapping[str, CameraMount]
    overhead: CameraModel
    overhead_pose: Transform

    def __post_init__(self) -> None:
        if set(self.cameras) != set(self.mounts):
            raise CalibrationError(
                f'calibration {self.name}: intrinsics for {sorted(self.cameras)} but mounts for '
                f'{sorted(self.mounts)}'
            )

    def save(self, directory: Path) -> list[Path]:
        """Write the calibration files into ``directory`` (made if missing); returns them."""
        directory.mkdir(parents=True, exist_ok=True)
        written = []
        for cid in sorted(self.cameras):
            model = self.cameras[cid]
            path = directory / f'{cid}.yaml'
            path.write_text(
                yaml.safe_dump({**model.to_dict(), 'camera_name': cid}, sort_keys=False)
            )
            written.append(path)
            mount = directory / f'{cid}_mount.yaml'
            mount.write_text(
                yaml.safe_dump(
                    {'camera_id': cid, 'mount': mount_to_dict(self.mounts[cid])}, sort_keys=False
                )
            )
            written.append(mount)
        over = directory / f'{OVERHEAD}.yaml'
        over.write_text(yaml.safe_dump({**self.overhead.to_dict(), 'camera_name': OVERHEAD}))
        pose = directory / f'{OVERHEAD}_pose.yaml'
        pose.write_text(yaml.safe_dump({'pose': pose_to_list(self.overhead_pose)}))
        return [*written, over, pose]


def _yaml(path: Path) -> dict[str, Any]:
    try:
        data = load_yaml(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise CalibrationError(f'cannot read {path}: {exc}') from exc
    if not isinstance(data, dict):
        raise CalibrationError(f'{path}: expected a mapping')
    return data


def load_calibration(
    directory: Path | str, nominal: Mapping[str, CameraMount] | None = None
) -> Calibration:
    """Read a calibration directory.

    Args:
        directory: the directory ``activesurv commission`` wrote.
        nominal: the set-up's mounts, for their joint names and linear axes where a file
            leaves them out.

    Raises:
        CalibrationError: naming the missing or malformed file.
    """
    d = Path(directory)
    if not d.is_dir():
        raise CalibrationError(f'calibration directory {d} does not exist')
    mounts_found = sorted(d.glob('*_mount.yaml'))
    if not mounts_found:
        raise CalibrationError(f'{d} holds no <camera>_mount.yaml: is it a calibration directory?')
    cameras: dict[str, CameraModel] = {}
    mounts: dict[str, CameraMount] = {}
    for path in mounts_found:
        cid = path.name[: -len('_mount.yaml')]
        data = _yaml(path)
        if not isinstance(data.get('mount'), dict):
            raise CalibrationError(f'{path}: needs a "mount" mapping')
        m = mount_from_dict(cid, data['mount'])
        if nominal is not None and cid in nominal:
            n = nominal[cid]
            m = CameraMount(
                cid,
                m.base,
                m.yaw_offset,
                m.pitch,
                m.offset,
                m.linear_axis if 'linear_axis' in data['mount'] else n.linear_axis,
                n.linear_joint,
                n.rotary_joint,
            )
        mounts[cid] = m
        cameras[cid] = CameraModel.load(d / f'{cid}.yaml')
    overhead = CameraModel.load(d / f'{OVERHEAD}.yaml')
    pose = pose_from_list(_yaml(d / f'{OVERHEAD}_pose.yaml').get('pose', []), 'overhead pose')
    return Calibration(str(d), cameras, mounts, overhead, pose)
