"""Every argument of an ``activesurv`` command checked before any long step.

A run starts with steps that take minutes (commissioning a rig, starting nodes); a bad argument
found after them wastes that time. :func:`check` looks at everything a command line says that
can be judged without running anything (numbers in range, files that exist and parse, names
that are known) and raises :class:`ConfigError` with a one-line reason at the first problem,
and builds on the way the option records the commands run with (:class:`Checked`): each
setting is checked once, where its record is built. A refusal comes within a second.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.experiments.faults import parse_fault, parse_kill
from activesurv_bringup.experiments.options import RunOptions
from activesurv_bringup.experiments.session_options import SurveilOptions
from activesurv_bringup.files import dds_profile_path
from activesurv_bringup.rig.hardware import read
from activesurv_bringup.rig.rigs import CALIBRATIONS, nominal_mounts
from activesurv_bringup.specs import live_view_spec
from activesurv_common.calibration import load_calibration
from activesurv_common.errors import CalibrationError
from activesurv_sim.rig import RigError, load_rig
from activesurv_sim.xytable import from_csv
from activesurv_stages.errors import ConfigError as StageConfigError

EXPECTED_PATHS = ('parabolic', 'diagonal')


def positive(name: str, value: float | None, allow_zero: bool = False) -> None:
    """``value`` is a finite number > 0 (>= 0 with ``allow_zero``); None passes."""
    if value is None:
        return
    ok = math.isfinite(value) and (value >= 0.0 if allow_zero else value > 0.0)
    if not ok:
        raise ConfigError(f'{name} must be {">=" if allow_zero else ">"} 0, got {value}')


def port(value: int | None) -> None:
    """A TCP port for ``--foxglove``."""
    if value is not None and not 1 <= value <= 65535:
        raise ConfigError(f'--foxglove {value}: a port is 1..65535')


def existing_file(name: str, path: Path | str | None) -> None:
    if path is not None and not Path(path).is_file():
        raise ConfigError(f'{name} {path}: no such file')


def rig_file(path: Path | None) -> None:
    """``--rig`` names a readable rig file."""
    if path is None:
        return
    existing_file('--rig', path)
    try:
        load_rig(path, nominal_mounts())
    except RigError as exc:
        raise ConfigError(f'--rig {path}: {exc}') from exc


def calibration(choice: str | None) -> None:
    """``--calibration`` is ``nominal``, ``truth`` or a calibration directory."""
    if choice is None or choice in CALIBRATIONS:
        return
    if not Path(choice).is_dir():
        raise ConfigError(
            f'--calibration {choice}: neither {" nor ".join(CALIBRATIONS)} nor a directory'
        )
    try:
        load_calibration(choice, nominal_mounts())
    except CalibrationError as exc:
        raise ConfigError(f'--calibration {choice}: {exc}') from exc


def trajectory(name: str, path: str | None) -> None:
    """A ``t,x,y`` CSV the xy table can run."""
    if path is None:
        return
    existing_file(name, path)
    try:
        from_csv(path)
    except (StageConfigError, ValueError) as exc:
        raise ConfigError(f'{name}: {exc}') from exc


def expect(value: str | None) -> None:
    if value is None or value in EXPECTED_PATHS:
        return
    if not Path(value).is_file():
        raise ConfigError(
            f'--expect {value}: neither {" nor ".join(EXPECTED_PATHS)} nor a CSV file'
        )
    trajectory('--expect', value)


def output_dir(name: str, path: Path | None) -> None:
    """A new or empty directory (nothing is ever overwritten)."""
    if path is None:
        return
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise ConfigError(f'{name} {path}: exists and is not empty (nothing is overwritten)')


def session(args: argparse.Namespace) -> SurveilOptions:
    """A surveillance session's options (its rig is chosen later, after the checks)."""
    opts = SurveilOptions.from_args(args)
    if args.objects_at_once > 1 and getattr(args, 'hardware', None) is not None:
        raise ConfigError(
            '--objects-at-once > 1 needs the simulator: a real xy table carries one object'
        )
    return opts


def run_options(args: argparse.Namespace) -> RunOptions:
    """The run options of an ``experiment``, ``surveil`` or ``demo`` command line.

    Raises:
        ConfigError: for a malformed fault, kill or profile, or options that do not mix.
    """
    profile = getattr(args, 'dds_profile', None)
    port = getattr(args, 'foxglove', None)
    return RunOptions(
        extra=() if port is None else (live_view_spec(port),),
        preview_rate=0.0 if port is None else 12.0,  # >= 10 Hz in the live view
        rtf=float(args.rtf),
        image_rate=float(getattr(args, 'image_rate', 2.0)),
        faults=tuple(parse_fault(f) for f in getattr(args, 'fault', None) or []),
        kills=tuple(parse_kill(k) for k in getattr(args, 'kill', None) or []),
        compose=bool(getattr(args, 'compose', False)),
        processes=str(getattr(args, 'processes', 'containers')),
        hosts=str(getattr(args, 'hosts', 'single')),
        dds_profile=dds_profile_path(profile) if profile else None,
        record_frames=str(getattr(args, 'record_frames', 'used')),
    )


@dataclass(frozen=True)
class Checked:
    """What a command line says, built once while it is checked (the commands take these,
    never the raw arguments again).

    Attributes:
        run: an experiment's, session's or demo's run options.
        surveil: a session's options (its rig chosen when it runs).
        controllers: ``activesurv lab --controller NAME=PORT``.
        delays, offsets: ``activesurv lab --exposure-delay / --clock-offset NAME=S``.
    """

    run: RunOptions | None = None
    surveil: SurveilOptions | None = None
    controllers: Mapping[str, str] = field(default_factory=dict)
    delays: Mapping[str, float] = field(default_factory=dict)
    offsets: Mapping[str, float] = field(default_factory=dict)


def controllers(texts: list[str]) -> dict[str, str]:
    """``--controller NAME=PORT`` (repeatable) as {NAME: PORT}.

    Raises:
        ConfigError: for a malformed or repeated entry.
    """
    out: dict[str, str] = {}
    for text in texts:
        name, _, port = text.partition('=')
        name, port = name.strip(), port.strip()
        if not name or not port:
            raise ConfigError(f'--controller {text!r}: expected NAME=PORT (NAME: table or camN)')
        if name in out:
            raise ConfigError(f'--controller {name} given twice')
        out[name] = port
    return out


def timings(texts: list[str], flag: str, low: float, high: float) -> dict[str, float]:
    """``--exposure-delay NAME=S`` / ``--clock-offset NAME=S`` (repeatable) as {NAME: s}.

    Raises:
        ConfigError: for a malformed, repeated or out-of-range entry.
    """
    out: dict[str, float] = {}
    for text in texts:
        name, _, value = text.partition('=')
        name = name.strip()
        try:
            seconds = float(value)
        except ValueError:
            raise ConfigError(
                f'{flag} {text!r}: expected NAME=SECONDS (e.g. cam1=0.035)'
            ) from None
        if not name or not math.isfinite(seconds) or not low <= seconds <= high:
            raise ConfigError(f'{flag} {text!r}: NAME=S with S in {low:g}..{high:g} s')
        if name in out:
            raise ConfigError(f'{flag} {name} given twice')
        out[name] = seconds
    return out


def hardware(args: argparse.Namespace) -> None:
    """``--hardware``: a readable hardware file, and nothing that only a simulation has."""
    path = _get(args, 'hardware')
    if path is None:
        if _get(args, 'home'):
            raise ConfigError('--home needs --hardware (a simulated stage is always referenced)')
        return
    # A run checks the ports too; 'activesurv stop' must work whatever the ports say.
    moves = args.command == 'hardware' and _get(args, 'hardware_command') == 'measure-delay'
    run = args.command in ('experiment', 'surveil', 'commission') or moves
    read(path, ports=run, layout=args.command in ('experiment', 'surveil'))
    if args.command == 'commission' and not args.live:
        raise ConfigError('--hardware commissions the real rig: add --live')
    if run and not _get(args, 'yes') and not sys.stdin.isatty():
        raise ConfigError(
            f'activesurv {args.command} --hardware moves the stages: with no terminal to ask '
            'at, confirm with --yes'
        )
    clash = [
        flag
        for flag, bad in (
            ('--rig', _get(args, 'rig') is not None),
            ('--mode lockstep', _get(args, 'mode') == 'lockstep'),
            ('--compose', bool(_get(args, 'compose'))),
            ('--hosts netns', _get(args, 'hosts') == 'netns'),
            ('--kill', bool(_get(args, 'kill'))),
        )
        if bad
    ]
    if clash:
        raise ConfigError(f'--hardware runs on the real rig: {", ".join(clash)} cannot apply')


def scene(args: argparse.Namespace) -> None:
    """Set C is a scripted session of the node graph: what only Sets A and B take is refused."""
    clash = [
        flag
        for flag, bad in (
            ('--mode lockstep', _get(args, 'mode') == 'lockstep'),
            ('--trajectory', _get(args, 'trajectory')),
            ('--expect', _get(args, 'expect')),
            ('--fault', _get(args, 'fault')),
            ('--kill', _get(args, 'kill')),
            ('--hosts netns', _get(args, 'hosts') == 'netns'),
            ('--hardware', _get(args, 'hardware')),
            ('--compose', _get(args, 'compose')),
        )
        if bad
    ]
    if clash:
        raise ConfigError(
            f'--set C (two objects and a post, run as a node-graph session) does not take '
            f'{", ".join(clash)}: they are for Sets A and B'
        )


def _get(args: argparse.Namespace, name: str) -> Any:
    return getattr(args, name, None)


def check(args: argparse.Namespace) -> Checked:
    """Refuse a command line that cannot run, before anything runs.

    Raises:
        ConfigError: naming the first bad argument and why.
    """
    cmd = args.command
    # A run's and a session's settings are checked where they are held (RunOptions,
    # SurveilOptions, built below): here only what no record holds.
    if cmd == 'replay':
        positive('--rtf', _get(args, 'rtf'))
    positive('--timeout', _get(args, 'timeout'))
    port(_get(args, 'foxglove'))
    seed = _get(args, 'seed')
    if isinstance(seed, int) and seed < 0 and cmd != 'rig':
        raise ConfigError(f'--seed must be >= 0, got {seed}')
    stations = _get(args, 'stations')
    if isinstance(stations, int) and stations < 1:
        raise ConfigError(f'--stations must be >= 1, got {stations}')
    rig_seed = _get(args, 'rig_seed')
    if isinstance(rig_seed, int) and rig_seed < 0:
        raise ConfigError(f'--rig-seed must be >= 0, got {rig_seed}')
    hardware(args)
    if cmd == 'experiment' and _get(args, 'set_name') == 'C':
        scene(args)
    built: dict[str, Any] = {}
    if cmd == 'lab':
        built['controllers'] = controllers(_get(args, 'controller') or [])
        built['delays'] = timings(_get(args, 'exposure_delay') or [], '--exposure-delay', 0, 1)
        built['offsets'] = timings(_get(args, 'clock_offset') or [], '--clock-offset', -1, 1)
        positive('--frame-rate', _get(args, 'frame_rate'))
    if cmd in ('experiment', 'surveil', 'demo', 'lab', 'commission'):
        rig_file(_get(args, 'rig'))
    if cmd in ('experiment', 'surveil', 'demo'):
        calibration(_get(args, 'calibration'))
        built['run'] = run_options(args)
    if cmd == 'experiment':
        trajectory('--trajectory', _get(args, 'trajectory'))
        expect(_get(args, 'expect'))
    if cmd == 'surveil':
        built['surveil'] = session(args)
    if cmd == 'replay':
        bag = Path(args.bag)
        if not bag.exists():
            raise ConfigError(f'replay: no run or bag at {bag}')
    if cmd in ('experiment', 'surveil', 'replay', 'commission', 'lab'):
        output_dir('--out', _get(args, 'out'))
    if cmd == 'demo':
        output_dir('--out', _get(args, 'out'))
    return Checked(**built)
