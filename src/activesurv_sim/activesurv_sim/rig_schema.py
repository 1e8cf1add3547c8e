"""The schema of a rig file (the simulated hardware as it is; ``activesurv rig nominal``).

Unknown keys at every level the rig file itself defines are errors naming the nearest valid
key; numbers are finite and in range. A camera's ``camera_info`` (the camera_calibration
format) and the ``obstacles`` entries are checked by their own readers.
"""

from __future__ import annotations

from typing import Any

from pydantic import Field, ValidationError

from activesurv_common.schema import StrictModel, problems

Vector3 = tuple[float, float, float]


class RigMeta(StrictModel):
    name: str = Field('rig', min_length=1)
    seed: int | None = Field(None, ge=0, description='the seed the rig was perturbed with')


class MountSection(StrictModel):
    """A camera's mount (world frame); keys left out come from the set-up."""

    base: Vector3 | None = Field(None, description='rotary axis at the optical centre [m]')
    yaw_offset: float | None = Field(None, description='optical axis yaw at rotary 0 [rad]')
    pitch: float | None = Field(None, ge=-1.6, le=1.6, description='downward tilt [rad]')
    rotation_centre_offset: Vector3 | None = Field(
        None, description='optical centre relative to the axis, optical frame [m]'
    )
    offset: Vector3 | None = Field(None, description='the same in the platform frame [m]')
    linear_axis: Vector3 | None = Field(None, description="linear stage's world direction")


class StageAccuracy(StrictModel):
    linear: float = Field(0.0, ge=0.0, le=0.01, description='linear stage error std [m]')
    rotary: float = Field(0.0, ge=0.0, le=0.1, description='rotary stage error std [rad]')
    seed: int | None = Field(None, ge=0)


class OpticsSection(StrictModel):
    """A camera's lens and exposure (keys left out: the paper's, f/4 at 10 ms, linear,
    focused at the table's middle as seen from the camera)."""

    f_number: float | None = Field(None, ge=0.7, le=64.0, description='aperture f-number')
    focus_distance: float | None = Field(
        None, ge=0.05, le=100.0, description='distance the lens is focused at [m]'
    )
    exposure_time: float | None = Field(
        None, ge=1e-5, le=0.5, description='time the shutter is open [s]'
    )
    gamma: float | None = Field(
        None, ge=0.2, le=5.0, description='response: grey = 255 (radiance/full)^(1/gamma)'
    )
    focal_length: float | None = Field(None, ge=0.001, le=0.5, description='of the lens [m]')


class RigCamera(StrictModel):
    camera_info: dict[str, Any] | None = None
    optics: OpticsSection | None = None
    mount: MountSection | None = None
    stage_accuracy: StageAccuracy | None = None


class RigOverhead(StrictModel):
    camera_info: dict[str, Any] | None = None
    optics: OpticsSection | None = None
    pose: tuple[float, float, float, float, float, float, float] = Field(
        description='x, y, z [m], qx, qy, qz, qw of the overhead camera (world frame)'
    )


class RigTable(StrictModel):
    accuracy: tuple[float, float] = Field(
        (0.0, 0.0), description="the table's position error std, x and y [m]"
    )
    seed: int = Field(0, ge=0)


class RigFile(StrictModel):
    rig: RigMeta = RigMeta()
    cameras: dict[str, RigCamera] = Field(min_length=1)
    overhead: RigOverhead | None = None  # without it: an error naming overhead.pose
    xy_table: RigTable | None = None
    obstacles: list[dict[str, Any]] | None = None


def rig_problems(data: Any) -> list[str]:
    """Every mistake of a rig document, one line each naming its key path (empty: valid)."""
    if not isinstance(data, dict):
        return ['(top level): a rig file is a mapping (activesurv rig nominal writes one)']
    try:
        RigFile.model_validate(data)
    except ValidationError as exc:
        return problems(exc, RigFile)
    return []
