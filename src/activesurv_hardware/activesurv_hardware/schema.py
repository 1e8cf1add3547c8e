"""The schema of the hardware file (pydantic): what ``activesurv hardware check`` enforces and
``activesurv hardware schema`` exports as JSON Schema for an editor's YAML language server.

Unknown keys are errors that name the nearest valid key; closed sets are enums (trigger,
protocol, axis kind); every number is finite and in range with its unit in the message;
``trigger`` and ``exposure_delay`` are required (no silent defaults). A camera's ``stages`` and
the table's may be a path to a controller YAML: :func:`hardware_problems` reads it first and
checks it with the same schema (:mod:`activesurv_stages.schema`).

Cross-checks that need more than one section (joints driven twice, ports shared by
controllers that cannot share one) are :func:`cross_problems`; the camera layout's and the
ports' existence are the caller's (they need the layout file and the machine).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import Field, ValidationError, field_validator, model_validator

from activesurv_common.schema import StrictModel, problems
from activesurv_common.trigger import Trigger
from activesurv_sim.xytable import TABLE_JOINTS
from activesurv_stages.schema import DAISY_CHAINED, ControllerFile

# libyaml's parser where PyYAML has it: the same safe subset, about ten times faster.
_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)

Vector3 = tuple[float, float, float]
Range = tuple[float, float]


class SourceSection(StrictModel):
    """Where frames come from: ``topic:`` (a driver's image topic) or ``device:``."""

    topic: str | None = Field(None, min_length=1, description="a ROS 2 driver's image topic")
    camera_info: str | None = Field(
        None, min_length=1, description="the driver's camera_info topic (default: beside topic)"
    )
    device: str | int | None = Field(
        None, description='for our camera node: index, /dev/videoN, file, pipeline or URL'
    )
    width: int | None = Field(None, gt=0, description='capture width [px]')
    height: int | None = Field(None, gt=0, description='capture height [px]')
    fps: float | None = Field(None, gt=0.0, description='capture rate asked of the device [Hz]')
    fourcc: str | None = Field(None, min_length=4, max_length=4, description='pixel format')
    loop: bool | None = Field(None, description='replay a video file in a loop')

    @model_validator(mode='after')
    def _one_kind(self) -> SourceSection:
        if (self.topic is None) == (self.device is None):
            raise ValueError('give topic: IMAGE_TOPIC or device: DEVICE (exactly one)')
        options = [k for k in ('width', 'height', 'fps', 'fourcc', 'loop') if getattr(self, k)]
        if self.topic is not None and options:
            raise ValueError(f'{", ".join(options)}: only for a device: source')
        if self.device is not None and self.camera_info is not None:
            raise ValueError('camera_info: only for a topic: source')
        return self


class CameraSection(StrictModel):
    """One camera: its frames, their timing, and (dynamic cameras) its stages."""

    source: SourceSection
    trigger: Trigger = Field(description='hardware, software or free (required)')
    frame_rate: float = Field(gt=0.0, le=1000.0, description='frames per second [Hz]')
    exposure_delay: float = Field(
        ge=0.0, le=1.0, description="from the exposure to the frame's stamp [s]"
    )
    trigger_service: str | None = Field(
        None,
        min_length=1,
        description="software trigger of a driver's topic: its std_srvs/Trigger service "
        '(a device: source is triggered through our camera node)',
    )
    trigger_lead: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description='software trigger: called this long before the instant [s] (0 with a '
        'device: source: half a frame period)',
    )
    stages: ControllerFile | None = Field(
        None, description='the controller YAML stage_bridge reads (inline or a path)'
    )


class TableSection(StrictModel):
    stages: ControllerFile | None = Field(
        None, description="the xy table's controller (joints table_x, table_y); none: no truth"
    )

    @field_validator('stages')
    @classmethod
    def _joints(cls, v: ControllerFile | None) -> ControllerFile | None:
        if v is not None:
            joints = sorted(a.joint for a in v.axes)
            if joints != sorted(TABLE_JOINTS):
                raise ValueError(f'the table controller drives {list(TABLE_JOINTS)}, got {joints}')
        return v


class ObjectSection(StrictModel):
    top_height: float = Field(ge=0.0, le=1.0, description='plane of the top marker [m]')
    side_offset: Vector3 = Field(description='side marker centre minus top marker centre [m]')
    side_normal: Vector3 = Field(description='unit normal of the side marker')

    @field_validator('side_normal')
    @classmethod
    def _unit(cls, v: Vector3) -> Vector3:
        n = sum(c * c for c in v) ** 0.5
        if abs(n - 1.0) > 1e-3:
            raise ValueError(f'must be a unit vector (length 1), has length {n:.4f}')
        return v


class BoardSection(StrictModel):
    """The commissioning boards on the table carriage (what commissioning looks for)."""

    squares: tuple[int, int] = Field((9, 7), description='side board: inner-corner grid + 1')
    square_size: float = Field(0.004, gt=0.0, le=0.1, description='side board square [m]')
    offset: Vector3 = Field(
        (0.0, -0.03, 0.05), description='side board centre minus the carriage position [m]'
    )
    top_squares: tuple[int, int] = Field((9, 7), description='top board: squares per side')
    top_square_size: float = Field(0.012, gt=0.0, le=0.1, description='top board square [m]')
    top_height: float = Field(0.08, ge=0.0, le=1.0, description='top board plane [m]')

    @field_validator('squares', 'top_squares')
    @classmethod
    def _enough(cls, v: tuple[int, int]) -> tuple[int, int]:
        if min(v) < 3:
            raise ValueError(f'at least 3 x 3 squares, got {list(v)}')
        return v


class TableTravel(StrictModel):
    x: Range = Field(description="the table's x travel, world frame [m]")
    y: Range = Field(description="the table's y travel, world frame [m]")

    @field_validator('x', 'y')
    @classmethod
    def _ordered(cls, v: Range) -> Range:
        if not v[0] < v[1]:
            raise ValueError(f'need min < max, got [{v[0]}, {v[1]}] m')
        return v


class GeometrySection(StrictModel):
    table: TableTravel
    marker_radius: float = Field(gt=0.0, le=0.5, description='side marker radius [m]')
    top_marker_radius: float = Field(gt=0.0, le=0.5, description='top marker radius [m]')
    object: ObjectSection
    board: BoardSection = BoardSection()
    layout: str = Field(
        'paper', min_length=1, description='paper, or a set-up YAML of that format (a path)'
    )


class HardwareFile(StrictModel):
    """A real rig (see :mod:`activesurv_hardware.hardware_file`)."""

    name: str | None = Field(None, description="the rig's name (default: the file's stem)")
    namespace: str = Field('', description="ROS namespace of the rig's topics")
    calibration: str = Field(
        'calibration', min_length=1, description='directory commissioning writes (relative)'
    )
    home: bool = Field(False, description='home unreferenced axes when the bridges connect')
    geometry: GeometrySection
    cameras: dict[str, CameraSection] = Field(min_length=1)
    table: TableSection | None = None
    overhead: CameraSection

    @field_validator('namespace')
    @classmethod
    def _namespace(cls, v: str) -> str:
        ns = (v or '').strip('/')
        if ns and not all(p and p.replace('_', 'a').isalnum() for p in ns.split('/')):
            raise ValueError(f'letters, digits, _ and / only, got {v!r}')
        return ns

    @field_validator('cameras')
    @classmethod
    def _ids(cls, v: dict[str, CameraSection]) -> dict[str, CameraSection]:
        bad = [c for c in v if not (c and c.replace('_', 'a').isalnum()) or c == 'overhead']
        if bad:
            raise ValueError(f'camera ids are letters, digits and _ (not overhead), got {bad}')
        return v


def _read_stages(value: Any, base: Path, where: str, found: list[str]) -> Any:
    """A ``stages`` value as a document: a path is read (relative to the hardware file)."""
    if value in (None, 'none'):
        return None
    if isinstance(value, str):
        path = (base / value).resolve()
        try:
            return yaml.load(path.read_text(), Loader=_LOADER)
        except (OSError, yaml.YAMLError) as exc:
            found.append(f'{where}: cannot read {path}: {exc}')
            return None
    return value


def normalise(data: dict[str, Any], base: Path) -> tuple[dict[str, Any], list[str]]:
    """The document with every ``stages:`` path read in and ``table: none`` as null; the
    problems met doing so."""
    found: list[str] = []
    doc = dict(data)
    cams = doc.get('cameras')
    if isinstance(cams, dict):
        doc['cameras'] = {
            cid: (
                {
                    **c,
                    'stages': _read_stages(c.get('stages'), base, f'cameras.{cid}.stages', found),
                }
                if isinstance(c, dict) and 'stages' in c
                else c
            )
            for cid, c in cams.items()
        }
    t = doc.get('table')
    if t in ('none', None):
        doc['table'] = None
    elif isinstance(t, dict) and 'stages' in t:
        doc['table'] = {**t, 'stages': _read_stages(t.get('stages'), base, 'table.stages', found)}
    return doc, found


def cross_problems(hw: HardwareFile) -> list[str]:
    """Mistakes across sections: a joint driven twice, a port shared by controllers that
    cannot share one (only daisy-chained Zaber devices can, with distinct device numbers, one
    baud rate)."""
    found = [
        f'cameras.{cid}.stages: missing (required: the controller YAML of its stages)'
        for cid, cam in hw.cameras.items()
        if cam.stages is None
    ]
    if hw.overhead.stages is not None:
        found.append('overhead.stages: the static overhead camera has no stages')
    for cid, cam in [*hw.cameras.items(), ('overhead', hw.overhead)]:
        if cam.trigger is not Trigger.SOFTWARE:
            continue
        if cam.source.device is not None:
            if cam.trigger_service:
                found.append(
                    f'{"" if cid == "overhead" else "cameras."}{cid}.trigger_service: only for '
                    "a driver's topic: a device: source is triggered through our camera node"
                )
        elif not cam.trigger_service:
            found.append(
                f'{"" if cid == "overhead" else "cameras."}{cid}.trigger_service: missing '
                "(required with trigger: software: the driver's std_srvs/Trigger service)"
            )
        if cid == 'overhead':
            found.append('overhead.trigger: software: the overhead camera tracks a stream; free')
    controllers: list[tuple[str, ControllerFile]] = [
        (f'cameras.{cid}.stages', cam.stages) for cid, cam in hw.cameras.items() if cam.stages
    ]
    if hw.table is not None and hw.table.stages is not None:
        controllers.append(('table.stages', hw.table.stages))
    joints: dict[str, str] = {}
    for where, c in controllers:
        for a in c.axes:
            if a.joint in joints:
                found.append(f'{where}: joint {a.joint} is also driven by {joints[a.joint]}')
            joints.setdefault(a.joint, where)
    by_port: dict[str, list[tuple[str, ControllerFile]]] = {}
    for where, c in controllers:
        by_port.setdefault(c.controller.port, []).append((where, c))
    for port, users in by_port.items():
        if len(users) < 2:
            continue
        first = users[0][0]
        protocols = {c.controller.protocol for _, c in users}
        if len(protocols) > 1 or next(iter(protocols)) not in DAISY_CHAINED:
            for where, _ in users[1:]:
                found.append(
                    f'{where}.controller.port: one port {port} for several controllers (also '
                    f'{first}; only Zaber devices share a daisy chain)'
                )
            continue
        if len({c.controller.baud for _, c in users}) > 1:
            for where, _ in users[1:]:
                found.append(
                    f'{where}.controller.baud: the daisy chain on {port} has one baud rate '
                    f'(as {first})'
                )
        devices: dict[str, str] = {}
        for where, c in users:
            for i, a in enumerate(c.axes):
                d = str(a.axis).strip()
                if d in devices:
                    found.append(
                        f'{where}.axes[{i}].axis: device {d} on {port} is also {devices[d]}'
                    )
                devices.setdefault(d, f'{where}.axes[{i}]')
    return found


def layout_problems(hw: HardwareFile, layout: dict[str, tuple[str, ...]]) -> list[str]:
    """The file against the camera layout (camera id -> its joints): the same cameras, and each
    camera's stages drive exactly its joints."""
    found: list[str] = []
    for cid in sorted(set(layout) - set(hw.cameras)):
        near = [c for c in hw.cameras if c not in layout]
        extra = f' (is {near[0]} meant to be {cid}?)' if len(near) == 1 else ''
        found.append(f'cameras.{cid}: missing: the layout has camera {cid}{extra}')
    for cid in sorted(set(hw.cameras) - set(layout)):
        found.append(f'cameras.{cid}: not a camera of the layout ({", ".join(sorted(layout))})')
    for cid, cam in hw.cameras.items():
        if cid not in layout or cam.stages is None:
            continue
        have = [a.joint for a in cam.stages.axes]
        want = list(layout[cid])
        for i, j in enumerate(have):
            if j not in want:
                found.append(
                    f'cameras.{cid}.stages.axes[{i}].joint: {j} is not a joint of {cid} '
                    f'(its joints: {", ".join(want)})'
                )
        for j in want:
            if j not in have:
                found.append(f'cameras.{cid}.stages: no axis drives joint {j}')
    return found


def hardware_problems(data: Any, base: Path) -> tuple[HardwareFile | None, list[str]]:
    """The validated file and every mistake in it (the file is None when there are some)."""
    if not isinstance(data, dict):
        return None, ['(top level): a hardware file is a mapping (activesurv hardware template)']
    doc, found = normalise(data, base)
    try:
        hw = HardwareFile.model_validate(doc)
    except ValidationError as exc:
        return None, found + problems(exc, HardwareFile)
    found += cross_problems(hw)
    if hw.geometry.layout != 'paper' and not (base / hw.geometry.layout).is_file():
        found.append(f'geometry.layout: no set-up file {(base / hw.geometry.layout).resolve()}')
    return (None if found else hw), found


def json_schema() -> dict[str, Any]:
    """The hardware file's JSON Schema (for editors: ``# yaml-language-server: $schema=``)."""
    schema = HardwareFile.model_json_schema()
    defs = schema.get('$defs', {})
    path = {'type': 'string', 'description': 'a controller YAML file (relative to this file)'}
    for name in ('CameraSection', 'TableSection'):
        stages = defs.get(name, {}).get('properties', {}).get('stages')
        if stages is not None and 'anyOf' in stages:
            stages['anyOf'].append(path)
    table = schema.get('properties', {}).get('table')
    if table is not None and 'anyOf' in table:
        table['anyOf'].append({'const': 'none', 'description': 'no table: runs carry no truth'})
    schema['$schema'] = 'https://json-schema.org/draft/2020-12/schema'
    schema['title'] = 'activesurv hardware file'
    return schema
