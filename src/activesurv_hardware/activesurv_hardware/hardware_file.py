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

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from activesurv_hardware.errors import HardwareFileError
from activesurv_stages.config import ControllerConfig, controller_from_dict
from activesurv_stages.errors import StageError

TRIGGERS = ('hardware', 'software', 'free')
SOURCE_KINDS = ('topic', 'device')
TABLE_JOINTS = ('table_x', 'table_y')


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


@dataclass(frozen=True)
class ObjectGeometry:
    top_height: float
    side_offset: tuple[float, float, float]
    side_normal: tuple[float, float, float]


@dataclass(frozen=True)
class Geometry:
    table_x: tuple[float, float]
    table_y: tuple[float, float]
    marker_radius: float
    top_marker_radius: float
    object: ObjectGeometry
    layout: str  # 'paper' or a set-up YAML path (resolved)
    board: Mapping[str, Any]


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

    @property
    def camera_ids(self) -> tuple[str, ...]:
        return tuple(self.cameras)

    def topic(self, relative: str) -> str:
        """A topic of the rig's namespace (``camN/image_raw`` -> ``/<ns>/camN/image_raw``)."""
        ns = self.namespace.strip('/')
        return f'/{ns}/{relative}' if ns else f'/{relative}'


def _number(d: Mapping[str, Any], key: str, where: str, above: float | None = None) -> float:
    try:
        v = float(d[key])
    except KeyError:
        raise HardwareFileError(f'{where}: missing {key}') from None
    except (TypeError, ValueError):
        raise HardwareFileError(f'{where}.{key}: not a number: {d[key]!r}') from None
    if not math.isfinite(v) or (above is not None and not v > above):
        bound = '' if above is None else f' > {above:g}'
        raise HardwareFileError(f'{where}.{key}: must be a finite number{bound}, got {v}')
    return v


def _pair(value: Any, where: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise HardwareFileError(f'{where}: expected [min, max] in metres, got {value!r}') from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise HardwareFileError(f'{where}: need finite min < max, got [{lo}, {hi}]')
    return lo, hi


def _vector(value: Any, where: str) -> tuple[float, float, float]:
    try:
        x, y, z = (float(v) for v in value)
    except (TypeError, ValueError):
        raise HardwareFileError(f'{where}: expected [x, y, z], got {value!r}') from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise HardwareFileError(f'{where}: not finite: {value!r}')
    return x, y, z


def _section(d: Mapping[str, Any], key: str, where: str) -> Mapping[str, Any]:
    v = d.get(key)
    if not isinstance(v, Mapping):
        raise HardwareFileError(f'{where}: missing section {key!r} (a mapping)')
    return v


def _stages(value: Any, base: Path, where: str) -> tuple[ControllerConfig, dict[str, Any]]:
    """A stage controller YAML given inline or as a path (relative to the hardware file)."""
    if isinstance(value, str):
        path = (base / value).resolve()
        try:
            data = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise HardwareFileError(f'{where}: cannot read {path}: {exc}') from exc
    else:
        data = value
    if not isinstance(data, dict):
        raise HardwareFileError(f'{where}: a controller YAML (controller:, axes:) is needed')
    try:
        return controller_from_dict(data), data
    except (StageError, ValueError, KeyError, TypeError) as exc:
        raise HardwareFileError(f'{where}: {exc}') from exc


def _source(d: Mapping[str, Any], camera_id: str, where: str) -> ImageSource:
    src = d.get('source')
    if not isinstance(src, Mapping) or not (set(src) & set(SOURCE_KINDS)):
        raise HardwareFileError(f'{where}.source: give topic: IMAGE_TOPIC or device: DEVICE')
    if 'topic' in src and 'device' in src:
        raise HardwareFileError(f'{where}.source: topic or device, not both')
    if 'topic' in src:
        topic = str(src['topic']).strip()
        if not topic:
            raise HardwareFileError(f'{where}.source.topic: empty')
        base = topic.rsplit('/', 1)[0] if '/' in topic else ''
        info = str(src.get('camera_info') or (f'{base}/camera_info' if base else 'camera_info'))
        return ImageSource('topic', topic, info)
    device = str(src['device']).strip()
    if not device:
        raise HardwareFileError(f'{where}.source.device: empty')
    options = {k: v for k, v in src.items() if k != 'device'}
    return ImageSource('device', device, '', options)


def _camera(camera_id: str, d: Any, base: Path, need_stages: bool) -> CameraEntry:
    where = f'cameras.{camera_id}' if need_stages else camera_id
    if not isinstance(d, Mapping):
        raise HardwareFileError(f'{where}: a mapping is needed')
    trigger = str(d.get('trigger', 'free'))
    if trigger not in TRIGGERS:
        raise HardwareFileError(f'{where}.trigger: one of {TRIGGERS}, got {trigger!r}')
    rate = _number(d, 'frame_rate', where, above=0.0)
    delay = _number({'exposure_delay': d.get('exposure_delay', 0.0)}, 'exposure_delay', where)
    if delay < 0.0 or delay > 1.0:
        raise HardwareFileError(f'{where}.exposure_delay: 0..1 s, got {delay}')
    stages: ControllerConfig | None = None
    raw: dict[str, Any] | None = None
    if need_stages:
        if 'stages' not in d:
            raise HardwareFileError(f'{where}: missing stages (its controller YAML)')
        stages, raw = _stages(d['stages'], base, f'{where}.stages')
    return CameraEntry(camera_id, _source(d, camera_id, where), trigger, rate, delay, stages, raw)


def load_hardware(path: Path | str) -> Hardware:
    """Read and check a hardware file.

    Raises:
        HardwareFileError: naming the first thing that is wrong and where.
    """
    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise HardwareFileError(f'cannot read hardware file {p}: {exc.strerror or exc}') from exc
    except yaml.YAMLError as exc:
        raise HardwareFileError(f'{p}: not YAML: {exc}') from exc
    if not isinstance(data, Mapping):
        raise HardwareFileError(f'{p}: a hardware file is a mapping (see activesurv hardware)')
    base = p.resolve().parent
    g = _section(data, 'geometry', 'geometry')
    table = _section(g, 'table', 'geometry')
    obj = _section(g, 'object', 'geometry')
    layout = str(g.get('layout', 'paper'))
    if layout != 'paper':
        lp = (base / layout).resolve()
        if not lp.is_file():
            raise HardwareFileError(f'geometry.layout: no set-up file {lp}')
        layout = str(lp)
    geometry = Geometry(
        _pair(table.get('x'), 'geometry.table.x'),
        _pair(table.get('y'), 'geometry.table.y'),
        _number(g, 'marker_radius', 'geometry', above=0.0),
        _number(g, 'top_marker_radius', 'geometry', above=0.0),
        ObjectGeometry(
            _number(obj, 'top_height', 'geometry.object'),
            _vector(obj.get('side_offset'), 'geometry.object.side_offset'),
            _vector(obj.get('side_normal'), 'geometry.object.side_normal'),
        ),
        layout,
        dict(g.get('board') or {}),
    )
    cams = data.get('cameras')
    if not isinstance(cams, Mapping) or not cams:
        raise HardwareFileError('cameras: at least one camera (id: {source, trigger, stages})')
    cameras = {str(cid): _camera(str(cid), c, base, True) for cid, c in cams.items()}
    joints: dict[str, str] = {}
    for cid, cam in cameras.items():
        for j in [a.joint for a in cam.stages.axes] if cam.stages else []:
            if j in joints:
                raise HardwareFileError(f'joint {j} of {cid} is also driven for {joints[j]}')
            joints[j] = cid
    table_cfg: ControllerConfig | None = None
    table_raw: dict[str, Any] | None = None
    t = data.get('table', 'none')
    stages = t.get('stages', 'none') if isinstance(t, Mapping) else t
    if stages not in (None, 'none'):
        table_cfg, table_raw = _stages(stages, base, 'table.stages')
        missing = [j for j in TABLE_JOINTS if j not in [a.joint for a in table_cfg.axes]]
        if missing:
            raise HardwareFileError(f'table.stages: the table controller needs joints {missing}')
    overhead = _camera('overhead', _section(data, 'overhead', 'hardware file'), base, False)
    ns = str(data.get('namespace', '') or '').strip('/')
    if ns and not all(part.replace('_', 'a').isalnum() for part in ns.split('/')):
        raise HardwareFileError(f'namespace: letters, digits, _ and / only, got {ns!r}')
    return Hardware(
        p.resolve(),
        str(data.get('name') or p.stem),
        ns,
        (base / str(data.get('calibration', 'calibration'))).resolve(),
        geometry,
        cameras,
        table_cfg,
        table_raw,
        overhead,
    )


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
# activesurv hardware file: a real rig for `activesurv experiment|surveil --hardware FILE` and
# `activesurv commission --live --hardware FILE`. Written by `activesurv hardware template` for
# the paper's rig (Table I, Fig. 4): four cameras on Zaber stages, a GRBL xy table, an overhead
# camera. Edit it for yours; `activesurv hardware check FILE` says what it understood.
# Units: SI (m, s, rad) except inside a controller's own units (si_per_unit converts).
name: {name}
namespace: {namespace}        # ROS namespace of the rig's topics; bridges obey only its goals
calibration: calibration      # written by commission --live, read by runs (relative to here)

geometry:
  table: {{x: [{x0:g}, {x1:g}], y: [{y0:g}, {y1:g}]}}   # m: the xy table's travel, world frame
  marker_radius: {marker:g}         # m: side marker (Table I: 25 mm diameter)
  top_marker_radius: {top:g}     # m: the top marker the overhead camera tracks
  object:                         # the object on the table carriage
    top_height: {top_height:g}             # m: plane of the top marker
    side_offset: {side_offset}  # m: side marker centre minus top marker centre
    side_normal: {side_normal}   # unit normal of the side marker
  board: {{columns: 9, rows: 6, square: 0.006}}   # commissioning checkerboard (m)
  layout: paper    # camera mounts, stage limits, initial poses: paper (paper_setup.yaml) or a
                   # set-up YAML of that format (relative to here)

# Per dynamic camera: where its frames come from, how it is triggered, and its stages.
#   source: {{topic: /cam1/image_raw}}        any ROS 2 camera driver (camera_info beside it;
#                                            best effort or reliable; mono8/16, rgb8, bgr8,
#                                            bayer_*, yuv422 are converted)
#   source: {{device: /dev/video0, width: 640, height: 480}}   our `camera` node (OpenCV
#                                            VideoCapture: an index, /dev/videoN, a video file,
#                                            a GStreamer pipeline or an rtsp:// URL)
#   trigger: hardware | software | free     free: the frame nearest the demand instant is taken
#                                            (within half a period) and corrected for motion
#   frame_rate: Hz; exposure_delay: s from the exposure to the frame's stamp
#   stages: the controller YAML stage_bridge reads (inline as here, or a path)
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
    marker_radius: float
    top_marker_radius: float
    object: ObjectGeometry
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
        marker=rig.marker_radius,
        top=rig.top_marker_radius,
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
