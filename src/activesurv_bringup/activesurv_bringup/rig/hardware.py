"""``activesurv hardware {template,check}``: a rig's hardware file, and the paper's as a start.

The file's format is :mod:`activesurv_hardware.hardware_file`'s. The template is the paper's
rig: the table's travel (Table I), the camera layout of ``paper_setup.yaml`` with each camera's
joints on a Zaber daisy chain at Table I's speeds, the object of ``experiments.yaml``, a GRBL
table, and every camera a ROS 2 driver's topic, free-running.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import yaml

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.files import config_path
from activesurv_bringup.rig.commission import TABLE_RANGE
from activesurv_bringup.rig.rigs import (
    CALIBRATIONS,
    RigChoice,
    layout_file,
    nominal,
    resolve_calibration,
)
from activesurv_dispatch.sensors import load_setup
from activesurv_hardware.errors import HardwareFileError
from activesurv_hardware.hardware_file import (
    Hardware,
    ObjectGeometry,
    TemplateRig,
    describe,
    load_hardware,
    template_text,
)
from activesurv_stages.config import motion_class


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
        setup.marker_radius,
        setup.marker_radius,
        ObjectGeometry(
            float(obj['top_height']),
            tuple(float(v) for v in obj['side_offset']),  # type: ignore[arg-type]
            tuple(float(v) for v in obj['side_normal']),  # type: ignore[arg-type]
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


def read(path: Path | str) -> Hardware:
    """A hardware file, or a one-line ConfigError."""
    try:
        return load_hardware(path)
    except HardwareFileError as exc:
        raise ConfigError(f'hardware file {path}: {exc}') from exc


def add_arguments(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``activesurv hardware {template,check}``."""
    t = sub.add_parser('template', help="write a commented hardware file (the paper's rig)")
    t.add_argument('--out', type=Path, required=True, help='file to write (must not exist)')
    t.add_argument('--name', default='paper-lab', help='the rig name in the file')
    t.add_argument('--namespace', default='', help="ROS namespace of the rig's topics")
    c = sub.add_parser('check', help='read a hardware file and say what it describes')
    c.add_argument('file', type=Path, help='the hardware file')


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
    return describe(read(args.file))
