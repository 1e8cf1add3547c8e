"""The hardware file: everything about a real rig that the code must not assume.

``activesurv hardware template --out lab.yaml`` writes a commented one (the paper's rig);
``activesurv hardware check lab.yaml`` reads it back and says what it found. Sections:

``name``, ``namespace``
    The rig's name, and the ROS namespace its nodes and topics live in (a hardware run's stage
    goals are ``<namespace>/<cam>/stage/goal``: bridges of another rig never see them).
``calibration``
    The directory ``activesurv commission --live --hardware`` writes and hardware runs read
    (relative to the file).
``geometry``
    The xy table's travel, the side marker's radius, the object (top marker height, side marker
    offset and normal), the commissioning boards, and the camera layout (``paper`` for the
    paper's ``paper_setup.yaml`` or a set-up YAML of that format: mounts, stage limits and the
    initial poses).
``cameras``
    Per dynamic camera: its image ``source`` (``topic:`` any ROS 2 driver's image topic, its
    ``camera_info`` beside it; or ``device:`` for our ``camera`` node: an index, ``/dev/videoN``,
    a video file, a GStreamer pipeline or an RTSP URL), its ``trigger`` (``hardware``,
    ``software`` or ``free``), ``frame_rate`` (Hz), ``exposure_delay`` (s from the exposure to
    the frame's stamp) and ``stages``: the stage controller YAML (inline, or a path), exactly as
    ``stage_bridge`` reads it.
``table``
    ``stages``: the xy table's controller YAML (joints ``table_x``, ``table_y``), or ``none``
    when something else moves the object (then runs carry no truth).
``overhead``
    The static overhead camera's source, trigger, rate and delay.

Everything is SI (m, s, rad) except what a controller YAML states in its own units.
"""

from __future__ import annotations

import getpass
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.trigger import SourceKind, Trigger
from activesurv_hardware.errors import HardwareFileError
from activesurv_hardware.rig_lock import holder
from activesurv_hardware.schema import (
    CameraSection,
    HardwareFile,
    hardware_problems,
)
from activesurv_sim.board import BoardFixture
from activesurv_stages.config import ControllerConfig, controller_from_dict

# libyaml's parser where PyYAML has it: the same safe subset, about ten times faster.
_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


@dataclass(frozen=True)
class ImageSource:
    """Where a camera's frames come from.

    Attributes:
        kind: ``topic`` (a ROS 2 driver publishes them) or ``device`` (our camera node opens it).
        value: the image topic, or the device (index, path, pipeline, URL).
        camera_info: the driver's camera_info topic (``topic`` sources; default beside the image).
        options: for ``device``: width, height, fps, fourcc, as OpenCV's capture properties.
    """

    kind: str
    value: str
    camera_info: str = ''
    options: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CameraEntry:
    camera_id: str
    source: ImageSource
    trigger: str
    frame_rate: float
    exposure_delay: float
    stages: ControllerConfig | None
    stages_dict: Mapping[str, Any] | None = None
    trigger_service: str = ''  # software trigger of a driver's topic (std_srvs/Trigger)
    trigger_lead: float = 0.0  # s: the service is called this long before the instant

    @property
    def software_trigger(self) -> tuple[str, float]:
        """(service, lead s) to call ahead of each instant; ('', 0) unless software-triggered.
        A ``device:`` source is our camera node, whose ``~/trigger`` publishes the first frame
        exposed after the call: called half a period ahead (unless ``trigger_lead`` says),
        that frame is the one nearest the instant."""
        if self.trigger != Trigger.SOFTWARE:
            return '', 0.0
        if self.source.kind == SourceKind.DEVICE:
            lead = self.trigger_lead or 0.5 / self.frame_rate
            return f'{self.camera_id}_camera/trigger', lead
        return self.trigger_service, self.trigger_lead


@dataclass(frozen=True)
class Geometry:
    table_x: tuple[float, float]
    table_y: tuple[float, float]
    object: ObjectGeometry  # the markers, their radii included
    layout: str  # 'paper' or a set-up YAML path (resolved)
    board: BoardFixture

    @property
    def marker_radius(self) -> float:
        """The side marker's radius (m)."""
        return self.object.side_radius

    @property
    def top_marker_radius(self) -> float:
        """The top marker's radius (m)."""
        return self.object.top_radius


@dataclass(frozen=True)
class Hardware:
    """A rig described by its hardware file (see the module docstring)."""

    path: Path
    name: str
    namespace: str
    calibration: Path
    geometry: Geometry
    cameras: Mapping[str, CameraEntry]
    table: ControllerConfig | None
    table_dict: Mapping[str, Any] | None
    overhead: CameraEntry
    home: bool = False  # home unreferenced axes on connect (the file's home: true)

    @property
    def camera_ids(self) -> tuple[str, ...]:
        return tuple(self.cameras)

    def topic(self, relative: str) -> str:
        """A topic of the rig's namespace (``camN/image_raw`` -> ``/<ns>/camN/image_raw``)."""
        ns = self.namespace.strip('/')
        return f'/{ns}/{relative}' if ns else f'/{relative}'


def _entry(camera_id: str, cam: CameraSection) -> CameraEntry:
    src = cam.source
    if src.topic is not None:
        topic = src.topic.strip()
        parent = topic.rsplit('/', 1)[0] if '/' in topic else ''
        info = src.camera_info or (f'{parent}/camera_info' if parent else 'camera_info')
        source = ImageSource('topic', topic, info)
    else:
        options = {
            k: v
            for k in ('width', 'height', 'fps', 'fourcc', 'loop')
            if (v := getattr(src, k)) is not None
        }
        source = ImageSource('device', str(src.device).strip(), '', options)
    stages = raw = None
    if cam.stages is not None:
        raw = cam.stages.model_dump(mode='json')
        stages = controller_from_dict(raw)
    return CameraEntry(
        camera_id,
        source,
        cam.trigger.value,
        cam.frame_rate,
        cam.exposure_delay,
        stages,
        raw,
        cam.trigger_service or '',
        cam.trigger_lead,
    )


def read_document(path: Path | str) -> Any:
    """The YAML document of a hardware file.

    Raises:
        HardwareFileError: if it cannot be read or is not YAML.
    """
    p = Path(path)
    try:
        return yaml.load(p.read_text(), Loader=_LOADER)
    except OSError as exc:
        raise HardwareFileError(f'cannot read hardware file {p}: {exc.strerror or exc}') from exc
    except yaml.YAMLError as exc:
        raise HardwareFileError(f'{p}: not YAML: {exc}') from exc


def validated(path: Path | str) -> HardwareFile:
    """The hardware file checked against its schema (:mod:`activesurv_hardware.schema`).

    Raises:
        HardwareFileError: listing every mistake, one line each, naming its key path.
    """
    p = Path(path)
    model, found = hardware_problems(read_document(p), p.resolve().parent)
    if model is None:
        raise HardwareFileError('\n'.join(found), found)
    return model


def load_hardware(path: Path | str) -> Hardware:
    """Read and check a hardware file.

    Raises:
        HardwareFileError: listing every mistake, one line each, naming its key path.
    """
    p = Path(path)
    model = validated(p)
    base = p.resolve().parent
    g = model.geometry
    o = g.object
    b = g.board
    layout = 'paper' if g.layout == 'paper' else str((base / g.layout).resolve())
    geometry = Geometry(
        g.table.x,
        g.table.y,
        ObjectGeometry(
            o.top_height,
            o.side_offset,
            o.side_normal,
            side_radius=g.marker_radius,
            top_radius=g.top_marker_radius,
        ),
        layout,
        BoardFixture(
            b.squares, b.square_size, b.offset, b.top_squares, b.top_square_size, b.top_height
        ),
    )
    table = model.table.stages if model.table is not None else None
    table_raw = table.model_dump(mode='json') if table is not None else None
    return Hardware(
        p.resolve(),
        model.name or p.stem,
        model.namespace,
        (base / model.calibration).resolve(),
        geometry,
        {cid: _entry(cid, cam) for cid, cam in model.cameras.items()},
        controller_from_dict(table_raw) if table_raw is not None else None,
        table_raw,
        _entry('overhead', model.overhead),
        model.home,
    )


def port_problems(hw: Hardware) -> list[str]:
    """Every controller port that does not exist or that this user cannot read and write."""
    found = []
    places = [(f'cameras.{c}.stages', cam.stages) for c, cam in hw.cameras.items()]
    places.append(('table.stages', hw.table))
    user = getpass.getuser()
    for where, cfg in places:
        if cfg is None:
            continue
        port = cfg.port
        key = f'{where}.controller.port'
        if not os.path.exists(port):
            found.append(
                f'{key}: {port} does not exist (is the controller plugged in and powered? '
                'ls -l /dev/serial/by-id/ lists serial adapters under stable names)'
            )
        elif not os.access(port, os.R_OK | os.W_OK):
            found.append(
                f'{key}: {port} is not readable and writable by {user} (sudo usermod -aG '
                'dialout $USER and log in again, or a udev rule: SUBSYSTEM=="tty", '
                'MODE="0660", GROUP="dialout")'
            )
        elif (held := holder(port)) is not None:
            found.append(
                f'{key}: {port} is in use by {held} (one run at a time on a rig: wait for it '
                'to end or stop it)'
            )
    return found


def describe(hw: Hardware) -> list[str]:
    """What ``activesurv hardware check`` prints: one line per part of the rig."""
    g = hw.geometry
    lines = [
        f'rig {hw.name!r} in namespace {hw.namespace or "(none)"}; calibration {hw.calibration}',
        f'table x {g.table_x[0]:g}..{g.table_x[1]:g} m, y {g.table_y[0]:g}..{g.table_y[1]:g} m; '
        f'marker radius {g.marker_radius * 1e3:g} mm; layout {g.layout}',
    ]
    for cam in [*hw.cameras.values(), hw.overhead]:
        stages = ''
        if cam.stages is not None:
            c = cam.stages
            stages = f'; {c.protocol} on {c.port}: {", ".join(a.joint for a in c.axes)}'
        lines.append(
            f'{cam.camera_id}: {cam.source.kind} {cam.source.value}, {cam.trigger} at '
            f'{cam.frame_rate:g} Hz, exposure delay {cam.exposure_delay * 1e3:g} ms{stages}'
        )
    if hw.table is None:
        lines.append('table: none (the object is moved by something else: no truth)')
    else:
        joints = ', '.join(a.joint for a in hw.table.axes)
        lines.append(f'table: {hw.table.protocol} on {hw.table.port}: {joints}')
    return lines


def stage_dict(controller: Mapping[str, Any], axes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """A controller YAML document (what ``stage_bridge`` reads) from its two parts."""
    return {'controller': dict(controller), 'axes': [dict(a) for a in axes]}


# -- the template --------------------------------------------------------------------------

HEADER = """\
# yaml-language-server: $schema=hardware.schema.json
# activesurv hardware file: a real rig for `activesurv experiment|surveil --hardware FILE` and
# `activesurv commission --live --hardware FILE`. Written by `activesurv hardware template` for
# the paper's rig (Table I, Fig. 4): four cameras on Zaber stages, a GRBL xy table, an overhead
# camera. Edit it for yours; `activesurv hardware check FILE` says what it understood, or every
# mistake with its key path. `activesurv hardware schema --out hardware.schema.json` writes the
# schema the first line names: an editor with the YAML language server then checks as you type.
# Units: SI (m, s, rad) except inside a controller's own units (si_per_unit converts).
name: {name}
namespace: {namespace}        # ROS namespace of the rig's topics; bridges obey only its goals
calibration: calibration      # written by commission --live, read by runs (relative to here)
home: false                   # true: home unreferenced axes when the bridges connect (or --home)

geometry:
  table: {{x: [{x0:g}, {x1:g}], y: [{y0:g}, {y1:g}]}}   # m: the xy table's travel, world frame
  marker_radius: {marker:g}         # m: side marker (Table I: 25 mm diameter)
  top_marker_radius: {top:g}     # m: the top marker the overhead camera tracks
  object:                         # the object on the table carriage
    top_height: {top_height:g}             # m: plane of the top marker
    side_offset: {side_offset}  # m: side marker centre minus top marker centre
    side_normal: {side_normal}   # unit normal of the side marker
  board:                          # the commissioning boards on the carriage (what commissioning
                                  # looks for; activesurv_sim.board.BoardFixture)
    squares: [9, 7]               # side board: squares (columns, rows)
    square_size: 0.004            # m: side board square
    offset: [0.0, -0.03, 0.05]    # m: side board centre minus the carriage position
    top_squares: [9, 7]           # top board (the overhead camera's): squares
    top_square_size: 0.012        # m: top board square
    top_height: 0.08              # m: top board plane
  layout: paper    # camera mounts, stage limits, initial poses: paper (paper_setup.yaml) or a
                   # set-up YAML of that format (relative to here)

# Per dynamic camera: where its frames come from, how it is triggered, and its stages.
#   source: {{topic: /cam1/image_raw}}        any ROS 2 camera driver (camera_info beside it;
#                                            best effort or reliable; mono8/16, rgb8, bgr8,
#                                            bayer_*, yuv422 are converted)
#   source: {{device: /dev/video0, width: 640, height: 480}}   our `camera` node (OpenCV
#                                            VideoCapture: an index, /dev/videoN, a video file,
#                                            a GStreamer pipeline or an rtsp:// URL)
#   trigger: hardware | software | free     (required) free: the frame nearest the demand
#                                            instant is taken and corrected for motion;
#                                            software: trigger_service (a driver's
#                                            std_srvs/Trigger) is called trigger_lead s ahead;
#                                            with a device: source our camera node is called
#                                            (default lead: half a frame period) and publishes
#                                            the first frame exposed after the call
#   frame_rate: Hz; exposure_delay: s from the exposure to the frame's stamp (required;
#     activesurv hardware measure-delay measures it)
#   stages: the controller YAML stage_bridge reads (inline as here, or a path):
#     controller: protocol zaber | grbl, port, baud (standard rates), poll_rate (Hz)
#     axes: joint (the layout's joint names), axis (Zaber device 1-99 / GRBL letter),
#       kind linear | rotary (required), si_per_unit (m or rad per controller unit), offset
#       (SI position at controller 0), min/max (soft limits, SI), max_velocity (SI/s),
#       max_acceleration (SI/s^2)
cameras:
"""

CAMERA = """\
  {cid}:
    source: {{topic: /{cid}/image_raw}}
    trigger: free
    frame_rate: 30.0
    exposure_delay: 0.02
    stages:
      controller: {{protocol: zaber, port: /dev/ttyUSB{n}, baud: 115200, poll_rate: 20.0}}
      axes:
"""

AXIS = """\
        - {{joint: {joint}, axis: '{axis}', kind: {kind}, si_per_unit: {unit}, offset: {lo:g}, \
min: {lo:g}, max: {hi:g}, max_velocity: {v:g}, max_acceleration: {a:g}}}
"""

TAIL = """\

# The xy table on a GRBL controller (X, Y in mm; its $ settings are left as found). `none` when
# the object is moved by something else: runs then carry no truth columns.
table:
  stages:
    controller: {{protocol: grbl, port: /dev/ttyACM0, baud: 115200, poll_rate: 20.0}}
    axes:
      - {{joint: table_x, axis: X, kind: linear, si_per_unit: 0.001, offset: {x0:g}, min: {x0:g}, \
max: {x1:g}, max_velocity: {v:g}, max_acceleration: {a:g}}}
      - {{joint: table_y, axis: Y, kind: linear, si_per_unit: 0.001, offset: {y0:g}, min: {y0:g}, \
max: {y1:g}, max_velocity: {v:g}, max_acceleration: {a:g}}}

overhead:
  source: {{topic: /overhead/image_raw}}
  trigger: free
  frame_rate: 10.0
  exposure_delay: 0.02
"""

# Zaber microstep sizes of Table I's stages: X-LSM linear, X-RSW rotary.
ZABER_LINEAR = 4.7625e-8  # m per microstep
ZABER_ROTARY = 4.0906154343617e-6  # rad per microstep


@dataclass(frozen=True)
class TemplateRig:
    """What the template is written from (the paper's rig unless told otherwise)."""

    name: str
    namespace: str
    table_x: tuple[float, float]
    table_y: tuple[float, float]
    object: ObjectGeometry  # the markers, their radii included
    cameras: Sequence[tuple[str, Sequence[tuple[str, str, float, float]]]]  # id, joints
    linear: tuple[float, float]  # max velocity, acceleration
    rotary: tuple[float, float]


def template_text(rig: TemplateRig) -> str:
    """A commented hardware file for ``rig`` (what ``activesurv hardware template`` writes)."""
    o = rig.object
    out = HEADER.format(
        name=rig.name,
        namespace=rig.namespace or "''",
        x0=rig.table_x[0],
        x1=rig.table_x[1],
        y0=rig.table_y[0],
        y1=rig.table_y[1],
        marker=o.side_radius,
        top=o.top_radius,
        top_height=o.top_height,
        side_offset=list(o.side_offset),
        side_normal=list(o.side_normal),
    )
    for n, (cid, joints) in enumerate(rig.cameras):
        out += CAMERA.format(cid=cid, n=n)
        for i, (joint, kind, lo, hi) in enumerate(joints, start=1):
            v, a = rig.linear if kind == 'linear' else rig.rotary
            unit = ZABER_LINEAR if kind == 'linear' else ZABER_ROTARY
            out += AXIS.format(
                joint=joint, axis=i, kind=kind, unit=f'{unit:.6g}', lo=lo, hi=hi, v=v, a=a
            )
    v, a = rig.linear
    return out + TAIL.format(
        x0=rig.table_x[0], x1=rig.table_x[1], y0=rig.table_y[0], y1=rig.table_y[1], v=v, a=a
    )
