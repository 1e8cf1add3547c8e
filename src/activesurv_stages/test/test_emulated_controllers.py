"""Drivers and bridge end to end through pyserial against the emulators on pseudo-terminals.

Every fault kind of the emulators is injected and the bridge must recover or report, without
ever writing a goal outside the soft limits to the port.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from activesurv_stages.bridge import BridgeWorker, LinkState, Snapshot
from activesurv_stages.config import AxisConfig
from activesurv_stages.drivers import GrblDriver, ZaberDriver
from activesurv_stages.emulators import (
    GrblAxisSpec,
    GrblEmulator,
    ZaberDeviceSpec,
    ZaberEmulator,
)
from activesurv_stages.errors import (
    CommunicationError,
    ControllerRejectedError,
    LimitError,
    StageError,
)
from activesurv_stages.kinematics import AxisLimits

UM = 1e-6  # the test stages: 1 microstep = 1 um, 1 urad

ZABER_AXES = [
    AxisConfig('cam1_x', '1', 'linear', UM, -0.15, AxisLimits(-0.15, 0.15, 0.1, 0.5)),
    AxisConfig('cam1_yaw', '2', 'rotary', UM, -1.0, AxisLimits(-1.0, 1.0, 0.2, 0.8)),
]
GRBL_AXES = [  # GRBL machine units: mm and degrees
    AxisConfig('cam4_x', 'X', 'linear', 1e-3, -0.15, AxisLimits(-0.15, 0.15, 0.1, 0.5)),
    AxisConfig(
        'cam4_yaw', 'A', 'rotary', 3.141592653589793 / 180, -1.0, AxisLimits(-1.0, 1.0, 0.2, 0.8)
    ),
]


@pytest.fixture
def zaber_emu(tmp_path: Path) -> Iterator[ZaberEmulator]:
    emu = ZaberEmulator(
        tmp_path / 'ttyZABER',
        [
            ZaberDeviceSpec(1, (0, 300_000), 300_000, 1_500_000),
            ZaberDeviceSpec(2, (0, 2_000_000), 1_000_000, 4_000_000, name='X-RSW60A'),
        ],
    )
    yield emu
    emu.close()


@pytest.fixture
def grbl_emu(tmp_path: Path) -> Iterator[GrblEmulator]:
    emu = GrblEmulator(
        tmp_path / 'ttyGRBL',
        [
            GrblAxisSpec('X', 300.0, 6000.0, 500.0),
            GrblAxisSpec('Y', 200.0, 1800.0, 100.0),
            GrblAxisSpec('Z', 50.0, 600.0, 50.0),
            GrblAxisSpec('A', 115.0, 12000.0, 50.0),
        ],
        homing_time=0.2,
    )
    yield emu
    emu.close()


def _wait(
    worker: BridgeWorker, pred: Callable[[Snapshot], bool], timeout: float = 30.0
) -> Snapshot:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        s = worker.snapshot()
        if pred(s):
            return s
        time.sleep(0.02)
    s = worker.snapshot()
    raise AssertionError(f'condition not reached: {s}')


def _at(joint: str, value: float, tol: float = 2e-6) -> Callable[[Snapshot], bool]:
    return lambda s: (
        s.state is LinkState.READY
        and abs(s.positions.get(joint, 1e9) - value) < tol
        and s.statuses.get(joint) == 'idle'
    )


def _raw_targets(received: list[bytes]) -> list[float]:
    """Every absolute target actually written to the wire (Zaber move abs, GRBL jogs)."""
    out = []
    for line in received:
        text = line.decode()
        m = re.search(r'move abs (-?\d+)', text)
        if m:
            out.append(float(m[1]))
        out += [float(v) for v in re.findall(r'[XYZA](-?\d+\.\d+)', text)]
    return out


def test_zaber_driver_direct(zaber_emu: ZaberEmulator) -> None:
    d = ZaberDriver(str(zaber_emu.link))
    assert d.connect() == ['1', '2']
    reports = d.poll()
    assert [r.needs_home for r in reports] == [True, True]
    with pytest.raises(ControllerRejectedError, match='BADDATA'):
        d.move('1', 1000, None)
    d.home('1')
    with pytest.raises(StageError, match='no Zaber device 7'):
        d.move('7', 0, None)
    d.close()
    with pytest.raises(CommunicationError, match='does not exist'):
        ZaberDriver('/dev/does-not-exist').connect()


def test_grbl_driver_direct(grbl_emu: GrblEmulator) -> None:
    d = GrblDriver(str(grbl_emu.link))
    assert d.connect() == ['X', 'Y', 'Z', 'A']
    assert d.poll()[0].status == 'fault'  # Alarm after power-up (homing enabled)
    with pytest.raises(ControllerRejectedError, match='error:9'):
        d.move('X', 1.0, 10.0)
    d.home('X')
    assert d.poll()[0].status == 'idle'
    with pytest.raises(ControllerRejectedError, match='error:15'):
        d.move('X', 400.0, 10.0)
    d.close()


def _settle(d: GrblDriver, deadline: float = 5.0) -> list[str]:
    end = time.monotonic() + deadline
    while (states := [r.status for r in d.poll()]) and 'busy' in states:
        assert time.monotonic() < end, states
        time.sleep(0.02)
    return states


def test_grbl_as_the_firmware_holds_and_jogs(tmp_path: Path) -> None:
    """What real GRBL 1.1 does and the emulator now does too: a feed hold at rest suspends it
    (Hold:0, jogs refused with error 8); the driver's stop never sends one at rest, so a goal
    after a stop still moves; jogs go in machine coordinates whatever work offset is set."""
    emu = GrblEmulator(
        tmp_path / 'ttyG',
        [GrblAxisSpec('X', 300.0, 6000.0, 500.0), GrblAxisSpec('Y', 200.0, 1800.0, 100.0)],
        homing_time=0.1,
        work_offset=[5.0, -2.0],  # a G10/G92 offset left by another program
    )
    d = GrblDriver(str(emu.link))
    try:
        d.connect()
        d.home('X')
        d.move('X', 20.0, 100.0)
        _settle(d)
        assert d.poll()[0].position == pytest.approx(20.0, abs=1e-3)  # MPos, not WPos + 5
        d.stop('X')  # at rest: the jog cancel only
        time.sleep(0.05)
        assert _settle(d) == ['idle', 'idle']
        d.move('X', 30.0, 10.0)  # still obeys (10 mm/s: a second's travel)
        time.sleep(0.3)
        d.stop('X')  # mid-jog: decelerates, back to Idle
        assert _settle(d) == ['idle', 'idle']
        assert 20.0 < d.poll()[0].position < 30.0
        # What a feed hold at rest does to the firmware: suspended, and the driver says so.
        d._line().write(b'!')
        time.sleep(0.05)
        report = d.poll()[0]
        assert report.status == 'fault'
        assert 'Hold:0' in report.detail
        with pytest.raises(ControllerRejectedError, match='error:8'):
            d.move('X', 10.0, 100.0)
        d._line().write(b'~')
        time.sleep(0.05)
        assert _settle(d) == ['idle', 'idle']
    finally:
        d.close()
        emu.close()


@pytest.mark.parametrize('protocol', ['zaber', 'grbl'])
def test_bridge_moves_and_recovers_from_every_fault(
    protocol: str, zaber_emu: ZaberEmulator, grbl_emu: GrblEmulator
) -> None:
    emu = zaber_emu if protocol == 'zaber' else grbl_emu
    axes = ZABER_AXES if protocol == 'zaber' else GRBL_AXES
    driver_cls = ZaberDriver if protocol == 'zaber' else GrblDriver
    joint = axes[0].joint
    w = BridgeWorker(
        lambda: driver_cls(str(emu.link), timeout=0.5),
        axes,
        poll_rate=25,
        reconnect_period=0.2,
        home_on_connect=True,  # asked: recovery includes homing again after a reset
    )
    w.start()
    try:
        _wait(w, lambda s: s.state is LinkState.READY)
        assert w.snapshot().counters['homings'] >= 1  # homed on first connect

        # (targets near home, the lower limit -0.15 m: short moves keep the test quick)
        w.submit_goal(joint, -0.13, 0.02)
        _wait(w, _at(joint, -0.13))

        # A goal outside the soft limits is refused before anything is written.
        sent_before = len(emu.received)
        with pytest.raises(LimitError, match='outside the soft limits'):
            w.submit_goal(joint, 0.2)
        with pytest.raises(LimitError):
            w.submit_goal(joint, float('nan'))
        time.sleep(0.2)
        assert not any(b'0.2' in line or b'350000' in line for line in emu.received[sent_before:])

        # Garbage on the line and dropped replies: skipped, or reconnected.
        emu.garbage(3)
        emu.drop_replies(1)
        w.submit_goal(joint, -0.12)
        s = _wait(w, _at(joint, -0.12))
        assert s.counters['garbage_lines'] >= 1 or s.counters['comm_errors'] >= 1

        # Unplugged: reported, then reconnected at the same path when it comes back.
        emu.unplug()
        s = _wait(w, lambda s: s.state is LinkState.DISCONNECTED, 5.0)
        assert 'communication lost' in s.last_error or 'connect failed' in s.last_error
        time.sleep(0.5)
        emu.replug()
        _wait(w, _at(joint, -0.12))

        # Controller reset: the reference is lost; the bridge re-homes and resends the goal.
        homings = w.snapshot().counters['homings']
        emu.reset()
        _wait(w, lambda s: s.counters['homings'] > homings and _at(joint, -0.12)(s))

        # A hung controller (stall of the line): silence, reconnect, carry on.
        emu.freeze(1.0)
        time.sleep(1.5)
        w.submit_goal(joint, -0.11)
        _wait(w, _at(joint, -0.11))

        # Nothing outside the soft limits ever reached the wire.
        lo, hi = axes[0].limits.min_position, axes[0].limits.max_position
        for raw in _raw_targets(emu.received):
            if protocol == 'zaber' and raw > 400_000:
                continue  # the rotary device's targets
            si = axes[0].to_si(raw)
            assert lo - 1e-9 <= si <= hi + 1e-9, (raw, si)
    finally:
        w.shutdown()


def test_zaber_stall_is_reported_as_a_fault(zaber_emu: ZaberEmulator) -> None:
    w = BridgeWorker(
        lambda: ZaberDriver(str(zaber_emu.link), timeout=0.5),
        ZABER_AXES,
        poll_rate=25,
        reconnect_period=0.2,
        home_on_connect=True,
    )
    w.start()
    try:
        _wait(w, lambda s: s.state is LinkState.READY)
        w.submit_goal('cam1_x', 0.1, 0.02)
        _wait(w, lambda s: s.statuses.get('cam1_x') == 'busy')
        zaber_emu.stall(1)
        s = _wait(w, lambda s: s.statuses.get('cam1_x') == 'fault', 5.0)
        assert s.positions['cam1_x'] < 0.1
        # A new goal is refused by the stalled device (reported), until it is homed again.
        w.submit_goal('cam1_x', 0.0)
        _wait(w, lambda s: s.counters['rejected_goals'] >= 1, 5.0)
    finally:
        w.shutdown()


@pytest.mark.parametrize('protocol', ['zaber', 'grbl'])
def test_a_bridge_never_homes_unless_asked(
    protocol: str, zaber_emu: ZaberEmulator, grbl_emu: GrblEmulator
) -> None:
    emu = zaber_emu if protocol == 'zaber' else grbl_emu
    axes = ZABER_AXES if protocol == 'zaber' else GRBL_AXES
    driver_cls = ZaberDriver if protocol == 'zaber' else GrblDriver
    w = BridgeWorker(lambda: driver_cls(str(emu.link), timeout=0.5), axes, poll_rate=25)
    w.start()
    try:
        _wait(w, lambda s: bool(s.positions))
        w.submit_goal(axes[0].joint, 0.01, 0.02)
        s = _wait(w, lambda s: s.counters['refused_unreferenced'] >= 1, 5.0)
        assert 'no reference position' in s.last_error
        assert s.counters['homings'] == 0
        sent = b''.join(emu.received)
        assert b'home' not in sent
        assert b'$H' not in sent
        assert b'move abs' not in sent
        assert b'$J=' not in sent
    finally:
        w.shutdown()


def test_grbl_moves_the_axes_of_one_goal_in_one_command(grbl_emu: GrblEmulator) -> None:
    w = BridgeWorker(
        lambda: GrblDriver(str(grbl_emu.link), timeout=0.5),
        GRBL_AXES,
        poll_rate=25,
        home_on_connect=True,
    )
    w.start()
    try:
        _wait(w, lambda s: s.state is LinkState.READY)
        x, y = GRBL_AXES[0].joint, GRBL_AXES[1].joint
        refused = w.submit_goals([(x, -0.13, 0.02), (y, -0.95, 0.05)])  # 20 mm, 2.9 deg
        assert refused == []
        _wait(w, lambda s: abs(s.positions[x] + 0.13) < 1e-4 and abs(s.positions[y] + 0.95) < 1e-4)
        jogs = [r for r in grbl_emu.received if r.startswith(b'$J=')]
        assert any(b'X' in j and b'A' in j for j in jogs), jogs  # one command, both axes
    finally:
        w.shutdown()


def _still_at(driver: ZaberDriver | GrblDriver, axis: str) -> float:
    """Connect a fresh driver and return where ``axis`` stands, checking that it stands still."""
    driver.connect()
    try:
        deadline = time.monotonic() + 2.0  # it may still be decelerating
        while (first := {r.axis: r for r in driver.poll()}[axis]).status != 'idle':
            assert time.monotonic() < deadline, first
            time.sleep(0.02)
        time.sleep(0.3)
        second = {r.axis: r for r in driver.poll()}[axis]
    finally:
        driver.close()
    assert second.status == 'idle', second
    assert abs(second.position - first.position) < 1e-9, (first, second)
    return float(second.position)


@pytest.mark.parametrize('protocol', ['zaber', 'grbl'])
@pytest.mark.parametrize('way', ['stop_all', 'estop', 'shutdown'])
def test_every_way_out_stops_the_axes(
    protocol: str, way: str, zaber_emu: ZaberEmulator, grbl_emu: GrblEmulator
) -> None:
    """~/stop, the e-stop and the bridge's shutdown (SIGINT, SIGTERM, a gone orchestrator) send
    the protocol's own stop: the axis stands still well short of a far goal."""
    emu = zaber_emu if protocol == 'zaber' else grbl_emu
    axes = ZABER_AXES if protocol == 'zaber' else GRBL_AXES
    driver_cls = ZaberDriver if protocol == 'zaber' else GrblDriver
    joint, axis = axes[0].joint, axes[0]
    w = BridgeWorker(
        lambda: driver_cls(str(emu.link), timeout=0.5),
        axes,
        poll_rate=25,
        home_on_connect=True,
    )
    w.start()
    stopped_in = 0.0
    try:
        _wait(w, lambda s: s.state is LinkState.READY)
        w.submit_goal(joint, 0.14, 0.02)  # 29 cm at 2 cm/s: 14 s of travel
        _wait(w, lambda s: s.statuses.get(joint) == 'busy' and s.positions[joint] > -0.145)
        t0 = time.monotonic()
        if way == 'stop_all':
            w.stop_all()
        elif way == 'estop':
            w.set_estop(True)
        else:
            w.shutdown()
        if way != 'shutdown':
            _wait(w, lambda s: s.statuses.get(joint) == 'idle', timeout=5.0)
            stopped_in = time.monotonic() - t0
            assert w.standing_still()
            assert w.snapshot().counters['stops_sent'] >= 1
        if way == 'estop':
            with pytest.raises(StageError, match='e-stop'):
                w.submit_goal(joint, 0.0)
            assert w.submit_goals([(joint, 0.0, None)])[0].endswith(
                'goal refused (activesurv stop --release)'
            )
            w.set_estop(False)
            w.submit_goal(joint, -0.14, 0.05)  # released: goals accepted again
            _wait(w, _at(joint, -0.14, tol=1e-4))
    finally:
        w.shutdown()
    if way == 'shutdown':
        stopped = axis.to_si(_still_at(driver_cls(str(emu.link), timeout=0.5), axis.axis))
        assert stopped < 0.0, stopped  # far short of the goal: the stop was sent on the way out
    else:
        assert stopped_in < 1.0, stopped_in  # a generous bound: the figure is in make bench
