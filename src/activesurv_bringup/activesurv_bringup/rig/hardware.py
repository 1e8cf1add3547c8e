"""``activesurv hardware {template,check,schema}``: a rig's hardware file; the paper's as a start.

The file's format is :mod:`activesurv_hardware.hardware_file`'s. The template is the paper's
rig: the table's travel (Table I), the camera layout of ``paper_setup.yaml`` with each camera's
joints on a Zaber daisy chain at Table I's speeds, the object of ``experiments.yaml``, a GRBL
table, and every camera a ROS 2 driver's topic, free-running.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

import yaml

from activesurv_bringup.errors import ConfigError, HardwareCheckError
from activesurv_bringup.files import config_path
from activesurv_bringup.rig.rigs import (
    CALIBRATIONS,
    RigChoice,
    layout_file,
    nominal,
    resolve_calibration,
)
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_dispatch.sensors import load_setup
from activesurv_hardware.errors import HardwareFileError
from activesurv_hardware.hardware_file import (
    Hardware,
    TemplateRig,
    describe,
    load_hardware,
    port_problems,
    read_document,
    template_text,
)
from activesurv_hardware.schema import hardware_problems, json_schema, layout_problems
from activesurv_sim.xytable import TABLE_ID, TABLE_JOINTS, TABLE_RANGE
from activesurv_stages.config import motion_class
from activesurv_stages.errors import StageError
from activesurv_stages.readout import read_positions


def paper_rig(name: str = 'paper-lab', namespace: str = '') -> TemplateRig:
    """The paper's rig as a template's input."""
    setup = load_setup(motion='fast')
    cfg = yaml.safe_load(config_path().read_text())
    obj = cfg['object']
    hw = motion_class('hardware')
    cameras = []
    for s in setup.sensors:
        kinds = (['linear'] if s.has_linear else []) + ['rotary']
        joints = [
            (j, k, lim.min_position, lim.max_position)
            for j, k, lim in zip(s.joint_names, kinds, s.limits, strict=True)
        ]
        cameras.append((s.camera_id, joints))
    return TemplateRig(
        name,
        namespace,
        TABLE_RANGE[0],
        TABLE_RANGE[1],
        ObjectGeometry(
            float(obj['top_height']),
            tuple(float(v) for v in obj['side_offset']),  # type: ignore[arg-type]
            tuple(float(v) for v in obj['side_normal']),  # type: ignore[arg-type]
            side_radius=setup.marker_radius,
            top_radius=setup.marker_radius,
        ),
        cameras,
        (hw.linear_velocity, hw.linear_acceleration),
        (hw.rotary_velocity, hw.rotary_acceleration),
    )


def hardware_layout(hw: Hardware) -> Path | None:
    """The set-up YAML of a hardware file's ``geometry.layout`` (None: the paper's)."""
    return layout_file(hw.geometry.layout)


def hardware_choice(hw: Hardware, calibration: str | None) -> RigChoice:
    """A hardware run's calibration (``calibration`` or the hardware file's own directory).

    The simulated rig of a :class:`RigChoice` plays no part in a hardware run (the nominal one
    of the file's ``geometry.layout`` stands in); the calibration is what every node is told,
    and a camera it does not hold keeps the layout's nominal mount.

    Raises:
        ConfigError: without a commissioned calibration, or one that misses a camera.
    """
    cal_dir = Path(calibration) if calibration else hw.calibration
    designed = nominal(hardware_layout(hw))
    if calibration in CALIBRATIONS:
        cal = resolve_calibration(str(calibration), designed)
    else:
        if not (cal_dir / 'commission.json').is_file() and not any(cal_dir.glob('*.yaml')):
            raise ConfigError(
                f'no calibration at {cal_dir}: commission the rig first (activesurv commission '
                f'--live --hardware {hw.path} --out {cal_dir})'
            )
        cal = resolve_calibration(str(cal_dir), designed)
    layout = {s.camera_id for s in load_setup(hardware_layout(hw)).sensors}
    if set(hw.cameras) != layout:
        raise ConfigError(
            f'{hw.path}: a run needs every camera of the layout {sorted(layout)}; the file has '
            f'{sorted(hw.cameras)}'
        )
    label = calibration if calibration in CALIBRATIONS else str(cal_dir.resolve())
    return RigChoice(designed, f'hardware {hw.path}', cal, str(label), hardware_layout(hw))


def check_hardware(path: Path | str, ports: bool = True, layout: bool = True) -> list[str]:
    """Every mistake of a hardware file, one line each naming its key path (empty: none).

    Beyond the schema: the cameras and joints against the file's camera layout (``layout``)
    and, for a run (``ports``), that every controller port exists and is usable.
    """
    p = Path(path)
    model, found = hardware_problems(read_document(p), p.resolve().parent)
    if model is None:
        return found
    hw = load_hardware(p)
    if layout:
        sensors = load_setup(hardware_layout(hw)).sensors
        found += layout_problems(model, {s.camera_id: tuple(s.joint_names) for s in sensors})
    if ports:
        found += port_problems(hw)
    return found


def read(path: Path | str, ports: bool = False, layout: bool = False) -> Hardware:
    """A hardware file, or a ConfigError listing every mistake (see :func:`check_hardware`)."""
    try:
        found = check_hardware(path, ports, layout)
    except HardwareFileError as exc:  # unreadable, not YAML
        raise HardwareCheckError(path, [f'(file): {exc}']) from exc
    if found:
        raise HardwareCheckError(path, found)
    return load_hardware(path)


def calibration_dir(hw: Hardware, calibration: str | None) -> Path:
    """The calibration directory a hardware run uses: ``--calibration DIR``, else the file's
    (``nominal``/``truth`` use the file's directory for what was measured there)."""
    if calibration and calibration not in CALIBRATIONS:
        return Path(calibration)
    return hw.calibration


def rig_ports(hw: Hardware) -> list[str]:
    """Every controller port of the rig (the cameras' stages and the table)."""
    configs = [cam.stages for cam in hw.cameras.values()] + [hw.table]
    return [c.port for c in configs if c is not None]


def current_positions(hw: Hardware) -> tuple[dict[str, float], list[str]]:
    """Every joint's position now, read from its controller without moving it; and a line per
    controller that could not be read (the bridges are not up yet: the ports are free)."""
    positions: dict[str, float] = {}
    unread = []
    controllers = [(cid, c.stages) for cid, c in hw.cameras.items()]
    controllers.append((TABLE_ID, hw.table))
    for name, config in controllers:
        if config is None:
            continue
        try:
            positions.update(read_positions(config))
        except StageError as exc:
            unread.append(f'{name}: positions not read ({exc})')
    return positions, unread


def motion_plan(
    hw: Hardware, command: str, home: bool, positions: Mapping[str, float] | None = None
) -> list[str]:
    """What a hardware run or commissioning will move, axis by axis (SI), before it moves;
    from where each stands when ``positions`` has it."""
    setup = load_setup(hardware_layout(hw), motion='fast')
    at = dict(positions or {})

    def where(joint: str, unit: str) -> str:
        return f'{at[joint]:+.4f} {unit}' if joint in at else 'where it stands'

    lines = []
    if home:
        lines.append('first: every axis without a reference position homes (--home)')
    for s in setup.sensors:
        if s.camera_id not in hw.cameras:
            continue
        kinds = (['linear'] if s.has_linear else []) + ['rotary']
        for joint, kind, lim, q in zip(
            s.joint_names, kinds, s.limits, setup.initial[s.camera_id], strict=True
        ):
            unit = 'm' if kind == 'linear' else 'rad'
            if command in ('commission', 'measure-delay'):
                lines.append(
                    f'{joint}: from {where(joint, unit)} over its range '
                    f'{lim.min_position:+.4f} .. {lim.max_position:+.4f} {unit} (board stations)'
                )
            else:
                lines.append(
                    f'{joint}: from {where(joint, unit)} to {q:+.4f} {unit}, then dispatched'
                )
    if hw.table is not None:
        g = hw.geometry
        what = (
            'the board grid'
            if command == 'commission'
            else 'back and forth in front of each camera'
            if command == 'measure-delay'
            else 'the experiment path'
        )
        start = (
            f'from ({at[TABLE_JOINTS[0]]:.4f}, {at[TABLE_JOINTS[1]]:.4f}) m '
            if all(j in at for j in TABLE_JOINTS)
            else ''
        )
        lines.append(
            f'table_x, table_y: {start}along {what} within x {g.table_x[0]:g}..'
            f'{g.table_x[1]:g} m, y {g.table_y[0]:g}..{g.table_y[1]:g} m'
        )
    return lines


def confirm_motion(
    hw: Hardware,
    command: str,
    yes: bool,
    home: bool,
    ask: Callable[[str], str] = input,
    say: Callable[[str], None] = print,
    read: Callable[[], tuple[dict[str, float], list[str]]] | None = None,
) -> None:
    """List what will move, from where it stands (``read``: default, each controller read once,
    nothing moved), and ask before the first motion (``--yes`` skips the question).

    Raises:
        ConfigError: if the answer is not yes, or there is no terminal to ask at.
    """
    if yes:
        return
    if not sys.stdin.isatty():
        raise ConfigError(
            f'activesurv {command} --hardware moves the stages of {hw.name}: with no terminal '
            'to ask at, confirm with --yes'
        )
    if read is None:

        def read() -> tuple[dict[str, float], list[str]]:
            return current_positions(hw)

    say(f'activesurv {command} will move these axes of {hw.name} ({hw.path}):')
    positions, unread = read()
    for line in [*motion_plan(hw, command, home, positions), *unread]:
        say(f'  {line}')
    answer = ask('Move them? Stop at any time with Ctrl-C or activesurv stop. [y/N] ')
    if answer.strip().lower() not in ('y', 'yes'):
        raise ConfigError('nothing moved: not confirmed')


def run(args: argparse.Namespace) -> list[str]:
    """Carry out ``activesurv hardware ...``; returns the lines to print.

    Raises:
        ConfigError: for an existing output file or a bad hardware file.
    """
    if args.hardware_command == 'template':
        out = Path(args.out)
        if out.exists():
            raise ConfigError(f'{out} exists; choose a new file (nothing is overwritten)')
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(template_text(paper_rig(args.name, args.namespace)))
        read(out)  # what we write must read back
        return [
            f'hardware file written: {out}',
            f'next: edit it, then activesurv hardware check {out}',
        ]
    if args.hardware_command == 'schema':
        out = Path(args.out)
        if out.exists():
            raise ConfigError(f'{out} exists; choose a new file (nothing is overwritten)')
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(json_schema(), indent=2) + '\n')
        return [
            f'JSON Schema written: {out}',
            f'first line of a hardware file beside it: # yaml-language-server: $schema={out.name}',
        ]
    return describe(read(args.file, ports=not args.offline, layout=True))
