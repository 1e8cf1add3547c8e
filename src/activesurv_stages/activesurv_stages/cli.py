"""``activesurv stages``: commissioning commands for real (or emulated) controllers.

::

    activesurv stages probe --protocol {zaber,grbl} --port PORT [--baud B]
    activesurv stages move  --protocol P --port PORT --axis ID --to VALUE [--baud B] [--home]
    activesurv stages emulate --protocol P --link PATH [--devices N]

``probe`` and ``move`` print one JSON line::

    {"protocol": "zaber", "axes": [{"axis": "1", "position": 12000, "status": "idle"}]}

Zaber axis ids are device numbers with positions in microsteps; GRBL axis ids are letters with
positions in machine units as GRBL reports them. On failure (no such port, no answer within the
timeout, a rejection or alarm) they print one line ``activesurv stages: error: <reason>`` to
stderr and exit with status 1. ``move`` does not home on its own: pass ``--home`` to home the
controller first (a Zaber device without a reference position, or GRBL in Alarm, refuses moves).
``emulate`` runs a controller emulator on a pseudo-terminal behind PATH until interrupted.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from activesurv_stages.drivers import DRIVERS, AxisReport, StageDriver, make_driver
from activesurv_stages.errors import StageError

WAIT_LIMIT = 600.0  # s: the longest a commissioning move may take


def _number(value: float) -> float | int:
    return int(value) if float(value).is_integer() else float(value)


def report_json(protocol: str, reports: list[AxisReport]) -> str:
    return json.dumps(
        {
            'protocol': protocol,
            'axes': [
                {'axis': r.axis, 'position': _number(r.position), 'status': r.status}
                for r in reports
            ],
        }
    )


def add_arguments(sub: Any) -> None:
    """Add the ``probe``, ``move`` and ``emulate`` subcommands to ``sub`` (argparse subparsers)."""
    for name, text in (
        ('probe', 'connect, find the axes, print their state as JSON'),
        ('move', 'move one axis to an absolute position and wait until idle'),
    ):
        p = sub.add_parser(name, help=text)
        p.add_argument(
            '--protocol', required=True, choices=sorted(DRIVERS), help='controller protocol'
        )
        p.add_argument('--port', required=True, help='serial port, e.g. /dev/ttyUSB0')
        p.add_argument('--baud', type=int, default=115200, help='serial baud rate')
        p.add_argument('--timeout', type=float, default=2.0, help='reply timeout (s)')
        if name == 'move':
            p.add_argument('--axis', required=True, help='Zaber device number or GRBL letter')
            p.add_argument('--to', required=True, type=float, help='absolute position (raw units)')
            p.add_argument('--speed', type=float, default=None, help='raw units/s')
            p.add_argument('--home', action='store_true', help='home the controller first')
    p = sub.add_parser('emulate', help='run a controller emulator on a pseudo-terminal')
    p.add_argument(
        '--protocol', required=True, choices=sorted(DRIVERS), help='controller protocol'
    )
    p.add_argument('--link', required=True, type=Path, help='path of the emulated port')
    p.add_argument('--devices', type=int, default=2, help='Zaber devices on the chain')
    p.add_argument('--homed', action='store_true', help='start homed / unlocked')


def _wait_idle(driver: StageDriver, axis: str) -> list[AxisReport]:
    deadline = time.monotonic() + WAIT_LIMIT
    while True:
        reports = driver.poll()
        mine = next((r for r in reports if r.axis == axis), None)
        if mine is None:
            raise StageError(f'axis {axis} disappeared from the controller')
        if mine.status == 'fault':
            raise StageError(f'axis {axis} reports a fault ({mine.detail})')
        if mine.status == 'idle':
            return reports
        if time.monotonic() > deadline:
            raise StageError(f'axis {axis} still busy after {WAIT_LIMIT:.0f} s')
        time.sleep(0.05)


def run(args: argparse.Namespace) -> int:
    """Execute a parsed ``stages`` subcommand; returns the exit status."""
    if args.stages_command == 'emulate':
        return _emulate(args)
    driver = make_driver(args.protocol, args.port, args.baud, args.timeout)
    try:
        try:
            axes = driver.connect()
            if args.stages_command == 'probe':
                print(report_json(args.protocol, driver.poll()), flush=True)
                return 0
            if args.axis not in axes:
                raise StageError(f'no axis {args.axis!r} on {args.port} (found {axes})')
            if args.home:
                driver.home(args.axis)
                _wait_idle(driver, args.axis)
            before = next(r for r in driver.poll() if r.axis == args.axis)
            if before.needs_home and not args.home:
                raise StageError(
                    f'axis {args.axis} has no reference position ({before.detail}); '
                    'home it first (--home)'
                )
            driver.move(args.axis, args.to, args.speed)
            print(report_json(args.protocol, _wait_idle(driver, args.axis)), flush=True)
            return 0
        finally:
            driver.close()
    except StageError as exc:
        print(f'activesurv stages: error: {exc}', file=sys.stderr, flush=True)
        return 1


def _emulate(args: argparse.Namespace) -> int:
    from activesurv_stages.emulators import (
        GrblAxisSpec,
        GrblEmulator,
        ZaberDeviceSpec,
        ZaberEmulator,
    )

    emu: ZaberEmulator | GrblEmulator
    if args.protocol == 'zaber':
        emu = ZaberEmulator(
            args.link,
            [
                ZaberDeviceSpec(n, (0, 1_000_000), 100_000, 400_000)
                for n in range(1, args.devices + 1)
            ],
        )
        if args.homed:
            for n in emu.homed:
                emu.homed[n] = True
    else:
        emu = GrblEmulator(
            args.link,
            [
                GrblAxisSpec('X', 300, 1500, 100),
                GrblAxisSpec('Y', 200, 1500, 100),
                GrblAxisSpec('Z', 50, 600, 50),
                GrblAxisSpec('A', 360, 3600, 200),
            ],
        )
        if args.homed:
            emu.state = 'Idle'
    print(f'emulating {args.protocol} on {args.link} -> {emu.device}; Ctrl-C to stop', flush=True)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        emu.close()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='activesurv stages',
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_arguments(parser.add_subparsers(dest='stages_command', required=True))
    return run(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
