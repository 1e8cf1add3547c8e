"""The commissioning commands' contract: one JSON line, or exit 1 with a one-line reason."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from activesurv_stages.emulators import (
    GrblAxisSpec,
    GrblEmulator,
    ZaberDeviceSpec,
    ZaberEmulator,
)

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def _run(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [ACTIVESURV, 'stages', *args], capture_output=True, text=True, timeout=timeout, check=False
    )


@pytest.fixture
def zaber(tmp_path: Path) -> Iterator[ZaberEmulator]:
    emu = ZaberEmulator(
        tmp_path / 'ttyZ',
        [
            ZaberDeviceSpec(1, (0, 500_000), 400_000, 2e6),
            ZaberDeviceSpec(2, (0, 500_000), 400_000, 2e6),
        ],
    )
    yield emu
    emu.close()


@pytest.fixture
def grbl_emu(tmp_path: Path) -> Iterator[GrblEmulator]:
    emu = GrblEmulator(
        tmp_path / 'ttyG',
        [
            GrblAxisSpec('X', 300, 6000, 500),
            GrblAxisSpec('Y', 200, 6000, 500),
            GrblAxisSpec('Z', 50, 600, 50),
        ],
        homing_time=0.1,
    )
    yield emu
    emu.close()


def _one_json_line(out: subprocess.CompletedProcess[str]) -> dict:  # type: ignore[type-arg]
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert len(lines) == 1, out.stdout
    data = json.loads(lines[0])
    assert set(data) == {'protocol', 'axes'}
    for axis in data['axes']:
        assert set(axis) == {'axis', 'position', 'status'}
        assert axis['status'] in ('idle', 'busy', 'fault')
        assert isinstance(axis['position'], (int, float))
    return data  # type: ignore[no-any-return]


def _one_line_error(out: subprocess.CompletedProcess[str], text: str) -> None:
    assert out.returncode != 0
    assert out.stdout == ''
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert 'Traceback' not in out.stderr
    assert text in lines[0], lines[0]


def test_zaber_probe_and_move(zaber: ZaberEmulator) -> None:
    data = _one_json_line(_run('probe', '--protocol', 'zaber', '--port', str(zaber.link)))
    assert data['protocol'] == 'zaber'
    assert [a['axis'] for a in data['axes']] == ['1', '2']
    _one_line_error(
        _run(
            'move',
            '--protocol',
            'zaber',
            '--port',
            str(zaber.link),
            '--axis',
            '2',
            '--to',
            '12345',
        ),
        'home it first',
    )
    data = _one_json_line(
        _run(
            'move',
            '--protocol',
            'zaber',
            '--port',
            str(zaber.link),
            '--axis',
            '2',
            '--to',
            '12345',
            '--home',
        )
    )
    assert data['axes'][1] == {'axis': '2', 'position': 12345, 'status': 'idle'}
    _one_line_error(
        _run(
            'move',
            '--protocol',
            'zaber',
            '--port',
            str(zaber.link),
            '--axis',
            '2',
            '--to',
            '900000',
        ),
        'rejected',
    )
    _one_line_error(
        _run('move', '--protocol', 'zaber', '--port', str(zaber.link), '--axis', '9', '--to', '0'),
        "no axis '9'",
    )


def test_grbl_probe_and_move(grbl_emu: GrblEmulator) -> None:
    data = _one_json_line(_run('probe', '--protocol', 'grbl', '--port', str(grbl_emu.link)))
    assert [a['axis'] for a in data['axes']] == ['X', 'Y', 'Z']
    assert data['axes'][0]['status'] == 'fault'  # Alarm: homing enabled, not homed yet
    data = _one_json_line(
        _run(
            'move',
            '--protocol',
            'grbl',
            '--port',
            str(grbl_emu.link),
            '--axis',
            'X',
            '--to',
            '12.5',
            '--home',
        )
    )
    assert data['axes'][0] == {'axis': 'X', 'position': 12.5, 'status': 'idle'}
    _one_line_error(
        _run(
            'move',
            '--protocol',
            'grbl',
            '--port',
            str(grbl_emu.link),
            '--axis',
            'X',
            '--to',
            '500',
        ),
        'error:15',
    )


def test_errors_missing_port_and_silence(tmp_path: Path, zaber: ZaberEmulator) -> None:
    _one_line_error(
        _run('probe', '--protocol', 'zaber', '--port', str(tmp_path / 'nope')), 'does not exist'
    )
    zaber.freeze(10.0)
    out = _run('probe', '--protocol', 'zaber', '--port', str(zaber.link))
    _one_line_error(out, 'within 2 s')
    _one_line_error(_run('probe', '--protocol', 'grbl', '--port', str(zaber.link)), 'within 2 s')
