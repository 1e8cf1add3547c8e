"""The command line's front door: --version, --help everywhere, bad arguments refused before any
long step (no commissioning, no nodes) with a one-line reason and no output directory left."""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import activesurv_bringup
from activesurv_bringup.cli import EXAMPLES, _build_parser

pytestmark = pytest.mark.cli

BIN = Path(sys.executable).parent


def _cli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.pop('ACTIVESURV_CALIBRATION', None)  # a refusal must come before any commissioning
    return subprocess.run(
        [str(BIN / 'activesurv'), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        check=False,
    )


def test_version() -> None:
    r = _cli('--version')
    assert r.returncode == 0
    assert r.stdout.strip() == f'activesurv {activesurv_bringup.__version__}'


def test_help_loads_no_heavy_library() -> None:
    """``activesurv --help`` builds every subcommand's parser without the ROS client library,
    numpy, pydantic, OpenCV or matplotlib (its time is in make bench, not here)."""
    code = (
        'import sys, activesurv_bringup.cli as c; c._build_parser(); '
        "print(sorted(m for m in ('rclpy', 'numpy', 'pydantic', 'cv2', 'matplotlib', 'scipy') "
        'if m in sys.modules))'
    )
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == '[]'


@pytest.mark.parametrize(
    'args',
    [
        ['surveil', '--out', '{out}', '--duration', '-5'],
        ['surveil', '--out', '{out}', '--rtf', '-1'],
        ['surveil', '--out', '{out}', '--demand-interval', '0'],
        ['surveil', '--out', '{out}', '--arrival-interval', 'nan'],
        ['surveil', '--out', '{out}', '--max-bag-duration', '-1'],
        ['surveil', '--out', '{out}', '--image-rate', '-1'],
        ['surveil', '--out', '{out}', '--demand-at', 'x=2'],
        ['surveil', '--out', '{out}', '--demand-at', 'y=0.1'],
        ['surveil', '--out', '{out}', '--foxglove', '99999'],
        [
            'experiment',
            '--set',
            'A',
            '--system',
            'fast',
            '--out',
            '{out}',
            '--trajectory',
            '/nonexistent.csv',
        ],
        ['experiment', '--set', 'A', '--system', 'fast', '--out', '{out}', '--expect', 'bogus'],
        ['experiment', '--set', 'A', '--system', 'fast', '--out', '{out}', '--image-rate', '-1'],
        ['experiment', '--set', 'A', '--system', 'fast', '--out', '{out}', '--rtf', '0'],
        ['experiment', '--set', 'A', '--system', 'fast', '--out', '{out}', '--fault', 'cam1:x'],
        [
            'experiment',
            '--set',
            'A',
            '--system',
            'fast',
            '--out',
            '{out}',
            '--calibration',
            '/nonexistent',
        ],
        [
            'experiment',
            '--set',
            'A',
            '--system',
            'fast',
            '--out',
            '{out}',
            '--rig',
            '/nonexistent.yaml',
        ],
        ['replay', '{tmp}', '--out', '{out}', '--rtf', '-2'],
        ['replay', '{tmp}', '--out', '{out}', '--rtf', '0'],
        ['replay', '/nonexistent', '--out', '{out}'],
        ['lab', '--rig', '/nonexistent.yaml', '--out', '{out}'],
        ['hardware', 'measure-delay', '--hardware', '/nonexistent.yaml', '--calibration', '{tmp}'],
        ['demo', '--out', '{out}', '--rtf', 'nan'],
    ],
)
def test_bad_arguments_are_refused_before_anything_runs(args: list[str], tmp_path: Path) -> None:
    out = tmp_path / 'out'
    r = _cli(*(a.format(out=out, tmp=tmp_path) for a in args))
    assert r.returncode != 0
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, r.stderr
    assert ': error: ' in lines[0]
    assert 'commissioning' not in r.stdout
    assert not out.exists(), 'a refused command left its output directory'


def test_a_non_empty_output_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / 'keep.txt').write_text('user data')
    r = _cli('surveil', '--out', str(tmp_path), '--duration', '10')
    assert r.returncode == 1
    assert 'not empty' in r.stderr
    assert (tmp_path / 'keep.txt').read_text() == 'user data'


def _flags(parser: object) -> list[tuple[str, object]]:
    out = []
    for action in parser._actions:  # type: ignore[attr-defined]
        choices = getattr(action, 'choices', None)
        if isinstance(choices, dict):  # sub-commands
            for name, sub in choices.items():
                out += [(f'{name} {flag}', act) for flag, act in _flags(sub)]
        elif action.option_strings:
            out.append((action.option_strings[-1], action))
    return out


def test_every_flag_has_help() -> None:
    missing = [flag for flag, act in _flags(_build_parser()) if not getattr(act, 'help', None)]
    assert not missing, f'flags without help: {missing}'


def test_the_help_overview_parses_and_names_every_command() -> None:
    """``activesurv --help`` ends with typical invocations: each parses with the real parser
    (a renamed flag or a dropped choice fails here), and every command has one."""
    parser = _build_parser()
    lines = [ln.split('#', 1)[0].strip() for ln in EXAMPLES.splitlines()]
    examples = [shlex.split(ln)[1:] for ln in lines if ln.startswith('activesurv ')]
    assert len(examples) >= 20
    for argv in examples:
        try:
            parser.parse_args(argv)
        except SystemExit as exc:
            pytest.fail(f'--help shows an invocation it refuses: {shlex.join(argv)} ({exc})')
    commands = next(a for a in parser._actions if a.dest == 'command').choices
    assert set(commands) == {argv[0] for argv in examples}, 'a command without an example'
    assert EXAMPLES in _cli('--help').stdout


def test_one_default_seed_and_a_rig_seed_of_its_own() -> None:
    parser = _build_parser()
    seeds = {
        cmd: parser.parse_args(argv).seed
        for cmd, argv in {
            'experiment': ['experiment', '--set', 'A', '--system', 'fast', '--out', 'x'],
            'surveil': ['surveil', '--out', 'x'],
            'demo': ['demo'],
        }.items()
    }
    assert len(set(seeds.values())) == 1, seeds
    args = parser.parse_args(['demo', '--seed', '7'])
    assert args.rig_seed != 7  # a new run seed is not a new rig (and no new commissioning)


@pytest.mark.parametrize(
    'script', ['fusion', 'predictor', 'imager', 'dispatcher', 'recorder', 'stage_bridge']
)
def test_node_scripts_answer_help(script: str) -> None:
    r = subprocess.run(
        [str(BIN / script), '--help'], capture_output=True, text=True, timeout=60, check=False
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f'usage: {script}')
    assert 'parameters:' in r.stdout
