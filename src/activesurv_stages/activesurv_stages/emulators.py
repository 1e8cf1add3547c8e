"""Motion-controller emulators on pseudo-terminals, driven by the kinematics core.

An emulator owns a pseudo-terminal (``os.openpty``, raw mode) and a stable symlink to its slave
side. The bridge opens that path with pyserial exactly as it would open ``/dev/ttyUSB0``, so the
real driver code runs end to end. Unplugging closes the pty and removes the link; replugging
creates a new pty behind the same link, as a USB adapter re-enumerating under a udev rule would.

Fault switches (thread-safe; set them while the emulator runs):

* ``drop_replies(n)``: the next n replies are not sent (lost on the wire).
* ``garbage(n)``: the next n replies are preceded by a line of random bytes.
* ``freeze(seconds)``: the controller ignores everything for a while (a hung controller).
* ``reset()``: the controller reboots: motion stops, homing is lost.
* ``stall(axis)``: the axis stalls and stops (Zaber: FS fault flag; GRBL cannot detect it).
* ``unplug()`` / ``replug()``: the serial device disappears / comes back at the same path.

Real time: the emulators run on ``time.monotonic()``.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import threading
import time
import tty
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activesurv_stages.errors import LimitError
from activesurv_stages.kinematics import AxisLimits, AxisSimulator
from activesurv_stages.protocols import grbl
from activesurv_stages.protocols.zaber import SPEED_UNIT


@dataclass
class Faults:
    """Pending fault injections (consumed as they take effect)."""

    drop: int = 0
    garbage: int = 0
    frozen_until: float = 0.0
    lock: threading.Lock = field(default_factory=threading.Lock)


class EmulatorBase:
    """A pty, its symlink, a reader thread, and the fault switches."""

    banner: bytes = b''

    def __init__(self, link: Path, seed: int = 0) -> None:
        self.link = Path(link)
        self.faults = Faults()
        self.rng = np.random.default_rng(seed)
        self._stop = threading.Event()
        self._buffer = b''
        self._master = -1
        self._slave = -1
        self._plugged = False
        self._io_lock = threading.Lock()
        self.received: list[bytes] = []  # every command line received (tests inspect it)
        self._open_pty()
        self._thread = threading.Thread(
            target=self._run, name=f'emulator:{self.link.name}', daemon=True
        )
        self._thread.start()

    # -- the pty ---------------------------------------------------------------------------
    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        tty.setraw(master)
        name = os.ttyname(slave)
        tmp = self.link.with_name(self.link.name + '.tmp')
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        tmp.symlink_to(name)
        tmp.replace(self.link)
        with self._io_lock:
            self._master, self._slave = master, slave
            self._buffer = b''
            self._plugged = True

    @property
    def device(self) -> str:
        return os.ttyname(self._slave) if self._plugged else ''

    def unplug(self) -> None:
        """The controller's USB cable is pulled: the port vanishes."""
        with self._io_lock:
            if not self._plugged:
                return
            self._plugged = False
            for fd in (self._master, self._slave):
                with contextlib.suppress(OSError):
                    os.close(fd)
        with contextlib.suppress(FileNotFoundError):
            self.link.unlink()

    def replug(self) -> None:
        """The cable is back: a new pty behind the same path; the controller powers up."""
        self.power_up()
        self._open_pty()
        if self.banner:
            self._send_raw(self.banner)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.unplug()

    def __enter__(self) -> EmulatorBase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- fault switches --------------------------------------------------------------------
    def drop_replies(self, n: int = 1) -> None:
        with self.faults.lock:
            self.faults.drop += n

    def garbage(self, n: int = 1) -> None:
        with self.faults.lock:
            self.faults.garbage += n

    def freeze(self, seconds: float) -> None:
        with self.faults.lock:
            self.faults.frozen_until = time.monotonic() + seconds

    # -- I/O -------------------------------------------------------------------------------
    def _send_raw(self, data: bytes) -> None:
        with self._io_lock:
            if not self._plugged:
                return
            with contextlib.suppress(OSError):
                os.write(self._master, data)

    def send(self, line: str) -> None:
        """Send one reply line, subject to the drop and garbage faults."""
        with self.faults.lock:
            if self.faults.drop > 0:
                self.faults.drop -= 1
                return
            junk = self.faults.garbage > 0
            if junk:
                self.faults.garbage -= 1
        if junk:
            noise = bytes(self.rng.integers(0, 256, int(self.rng.integers(3, 24))).tolist())
            self._send_raw(noise.replace(b'\n', b'?') + b'\r\n')
        self._send_raw(line.encode('ascii') + b'\r\n')

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._io_lock:
                master, plugged = self._master, self._plugged
            if not plugged:
                time.sleep(0.02)
                continue
            try:
                ready, _, _ = select.select([master], [], [], 0.01)
                data = os.read(master, 4096) if ready else b''
            except OSError:
                time.sleep(0.02)
                continue
            now = time.monotonic()
            with self.faults.lock:
                frozen = now < self.faults.frozen_until
            if data and not frozen:
                self.on_bytes(data, now)
            self.tick(now)

    def on_bytes(self, data: bytes, now: float) -> None:
        self._buffer += data
        while True:
            cut = [i for i in (self._buffer.find(b'\n'), self._buffer.find(b'\r')) if i >= 0]
            if not cut:
                break
            i = min(cut)
            line, self._buffer = self._buffer[:i], self._buffer[i + 1 :]
            if line.strip():
                self.received.append(line)
                self.on_line(line.decode('ascii', errors='replace').strip(), now)

    # -- protocol hooks --------------------------------------------------------------------
    def on_line(self, line: str, now: float) -> None:
        raise NotImplementedError

    def tick(self, now: float) -> None:
        """Called every ~10 ms (deferred replies)."""

    def power_up(self) -> None:
        """State after power-on or reset."""


# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ZaberDeviceSpec:
    """One device on the daisy chain (a single-axis stage), in microsteps.

    Attributes:
        number: device number (1, 2, ...).
        travel: (min, max) position in microsteps.
        max_speed: microsteps/s.
        acceleration: microsteps/s^2.
        home: position after homing.
        name: e.g. ``X-LSM200A`` or ``X-RSW60A`` (reported by ``get system.name``).
    """

    number: int
    travel: tuple[int, int]
    max_speed: float
    acceleration: float
    home: int = 0
    name: str = 'X-LSM200A'


class ZaberEmulator(EmulatorBase):
    """Daisy-chained Zaber ASCII devices (firmware-7 style replies)."""

    def __init__(self, link: Path, devices: Sequence[ZaberDeviceSpec], seed: int = 0) -> None:
        self.specs = {d.number: d for d in devices}
        self.axes: dict[int, AxisSimulator] = {}
        self.homed: dict[int, bool] = {}
        self.maxspeed: dict[int, float] = {}
        self.stalled: dict[int, bool] = {}
        self.interrupted: dict[int, bool] = {}
        self._state_lock = threading.RLock()
        self._message_id: int | None = None
        self.power_up()
        super().__init__(link, seed)

    def power_up(self) -> None:
        with self._state_lock:
            now = time.monotonic()
            for n, spec in self.specs.items():
                lim = AxisLimits(spec.travel[0], spec.travel[1], spec.max_speed, spec.acceleration)
                # After power-up the position is unknown; it reads as where the stage was.
                old = self.axes.get(n)
                pos = old.state(now)[0] if old else float(spec.home)
                self.axes[n] = AxisSimulator(
                    lim, min(max(pos, spec.travel[0]), spec.travel[1]), now
                )
                self.homed[n] = False
                self.maxspeed[n] = spec.max_speed
                self.stalled[n] = False
                self.interrupted[n] = False

    def reset(self) -> None:
        """``system reset`` or a power glitch: motion stops and the reference is lost."""
        self.power_up()

    def stall(self, device: int) -> None:
        with self._state_lock:
            now = time.monotonic()
            ax = self.axes[device]
            ax.set_position(now, ax.state(now)[0])
            self.stalled[device] = True

    def _warning(self, n: int) -> str:
        if self.stalled[n]:
            return 'FS'
        if not self.homed[n]:
            return 'WR'
        if self.interrupted[n]:
            return 'NI'
        return '--'

    def _reply(self, n: int, ok: bool, data: str, now: float) -> None:
        status = 'BUSY' if self.axes[n].busy(now) else 'IDLE'
        mid = '' if self._message_id is None else f' {self._message_id}'
        self.send(
            f'@{n:02d} 0{mid} {"OK" if ok else "RJ"} {status} {self._warning(n)} {data}'.rstrip()
        )

    def on_line(self, line: str, now: float) -> None:
        if not line.startswith('/'):
            return  # not a command: a real device discards it
        words = line[1:].split()
        device = 0
        self._message_id = None
        if words and words[0].isdigit():
            device = int(words.pop(0))
        if words and words[0].isdigit() and len(words[0]) == 1:
            axis = int(words.pop(0))
            if words and words[0].isdigit():
                self._message_id = int(words.pop(0))  # optional message id, echoed back
            if axis > 1:
                targets = [device] if device else sorted(self.specs)
                for n in targets:
                    if n in self.specs:
                        self._reply(n, False, 'BADAXIS', now)
                return
        targets = sorted(self.specs) if device == 0 else [device]
        with self._state_lock:
            for n in targets:
                if n in self.specs:
                    self._execute(n, words, now)

    def _execute(self, n: int, words: list[str], now: float) -> None:
        ax = self.axes[n]
        cmd = ' '.join(words[:2])
        try:
            if not words:
                self._reply(n, True, '0', now)
            elif cmd == 'get pos':
                self._reply(n, True, str(round(ax.state(now)[0])), now)
            elif cmd == 'get maxspeed':
                self._reply(n, True, str(round(self.maxspeed[n] * SPEED_UNIT)), now)
            elif cmd == 'get system.name':
                self._reply(n, True, self.specs[n].name, now)
            elif cmd == 'get limit.max':
                self._reply(n, True, str(self.specs[n].travel[1]), now)
            elif cmd == 'get limit.min':
                self._reply(n, True, str(self.specs[n].travel[0]), now)
            elif cmd == 'set maxspeed' and len(words) == 3:
                value = int(words[2]) / SPEED_UNIT
                if not 0 < value <= self.specs[n].max_speed * 1.0001:
                    self._reply(n, False, 'BADDATA', now)
                    return
                self.maxspeed[n] = value
                self._reply(n, True, '', now)
            elif cmd in ('move abs', 'move rel') and len(words) == 3:
                target = int(words[2]) + (round(ax.state(now)[0]) if cmd == 'move rel' else 0)
                if self.stalled[n] or not self.homed[n]:
                    self._reply(n, False, 'BADDATA', now)  # no reference: moves are refused
                    return
                if ax.busy(now):
                    self.interrupted[n] = True
                ax.command(now, float(target), self.maxspeed[n])
                self._reply(n, True, '', now)
            elif cmd == 'home':
                # Homing runs to the home sensor; modelled as a move at full speed.
                self.stalled[n] = False
                p = ax.state(now)[0]
                ax.set_position(now, p)
                ax.command(now, float(self.specs[n].home), self.specs[n].max_speed)
                self.homed[n] = True
                self._reply(n, True, '', now)
            elif cmd in ('stop', 'estop'):
                ax.stop(now)
                self._reply(n, True, '', now)
            elif cmd == 'warnings':
                w = self._warning(n)
                self._reply(n, True, '00' if w == '--' else f'01 {w}', now)
            elif cmd == 'system reset':
                self._reply(n, True, '', now)
                self.reset()
            else:
                self._reply(n, False, 'BADCOMMAND', now)
        except (ValueError, LimitError):
            self._reply(n, False, 'BADDATA', now)


# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GrblAxisSpec:
    """One GRBL axis in machine units (mm, or degrees for a rotary axis).

    Attributes:
        letter: X, Y, Z or A.
        travel: max travel from home (positions 0 .. travel).
        max_rate: units/min ($110...).
        acceleration: units/s^2 ($120...).
    """

    letter: str
    travel: float
    max_rate: float
    acceleration: float


class GrblEmulator(EmulatorBase):
    """A GRBL 1.1 controller with homing enabled and soft limits on.

    As the firmware behaves: jogs in machine (``G53``) or work coordinates (``G90``, the
    machine position minus ``work_offset``); a feed hold during a jog cancels it, a feed hold
    at rest suspends the controller (``Hold:0``: jogs refused with error 8 until ``~``);
    status reports carry ``WCO`` every tenth report and ``Ov`` every twentieth.
    """

    banner = b"\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n"

    def __init__(
        self,
        link: Path,
        axes: Sequence[GrblAxisSpec],
        seed: int = 0,
        homing_time: float = 0.3,
        work_offset: Sequence[float] | None = None,
    ) -> None:
        self.specs = list(axes)
        self.work_offset = [float(v) for v in work_offset or [0.0] * len(self.specs)]
        self._reports = 0
        self.homing_time = homing_time
        self.sims: dict[str, AxisSimulator] = {}
        self.state = 'Alarm'
        self._homing_done = 0.0
        self._held = False
        self._state_lock = threading.RLock()
        self.power_up()
        super().__init__(link, seed)

    def power_up(self) -> None:
        with self._state_lock:
            now = time.monotonic()
            for s in self.specs:
                lim = AxisLimits(0.0, s.travel, s.max_rate / 60.0, s.acceleration)
                old = self.sims.get(s.letter)
                pos = old.state(now)[0] if old else 0.0
                self.sims[s.letter] = AxisSimulator(lim, min(max(pos, 0.0), s.travel), now)
            self.state = 'Alarm'  # homing enabled: locked until $H or $X
            self._homing_done = 0.0
            self._held = False

    def reset(self) -> None:
        """Soft reset (0x18) or power cycle: motion stops, position is untrusted."""
        with self._state_lock:
            was_moving = any(s.busy(time.monotonic()) for s in self.sims.values())
            self.power_up()
        self._send_raw(self.banner)
        if was_moving:
            self.send('ALARM:3')

    def stall(self, letter: str) -> None:
        """Open-loop steppers lose steps silently: the axis just stops (GRBL cannot tell)."""
        with self._state_lock:
            now = time.monotonic()
            ax = self.sims[letter]
            ax.set_position(now, ax.state(now)[0])

    def _status(self, now: float) -> str:
        if self.state not in ('Alarm', 'Home'):
            busy = any(s.busy(now) for s in self.sims.values())
            self.state = (
                ('Hold:0' if self._held else 'Jog')
                if busy
                else ('Hold:0' if self._held else 'Idle')
            )
        pos = ','.join(f'{self.sims[s.letter].state(now)[0]:.3f}' for s in self.specs)
        self._reports += 1
        extra = ''
        if self._reports % 10 == 1:  # GRBL sends the work offset now and then, not every time
            extra += '|WCO:' + ','.join(f'{v:.3f}' for v in self.work_offset)
        if self._reports % 20 == 2:
            extra += '|Ov:100,100,100'
        return f'<{self.state}|MPos:{pos}|FS:0,0{extra}>'

    def on_bytes(self, data: bytes, now: float) -> None:
        # Real-time commands act immediately, wherever they appear in the stream.
        rest = bytearray()
        for b in data:
            c = bytes([b])
            if c == grbl.STATUS_QUERY:
                with self._state_lock:
                    self.send(self._status(now))
            elif c == grbl.FEED_HOLD:
                # GRBL 1.1: a feed hold during a jog cancels it (back to Idle); at rest it
                # suspends the controller (Hold:0) until a cycle start.
                with self._state_lock:
                    moving = any(s.busy(now) for s in self.sims.values())
                    for s in self.sims.values():
                        s.stop(now)
                    if not moving and self.state == 'Idle':
                        self._held = True
            elif c == grbl.CYCLE_START:
                self._held = False
            elif c == grbl.JOG_CANCEL:
                with self._state_lock:
                    for s in self.sims.values():
                        s.stop(now)
            elif c == grbl.SOFT_RESET:
                self.reset()
            else:
                rest += c
        if rest:
            super().on_bytes(bytes(rest), now)

    def tick(self, now: float) -> None:
        with self._state_lock:
            if self.state == 'Home' and now >= self._homing_done:
                for s in self.sims.values():
                    s.set_position(now, 0.0)
                self.state = 'Idle'
                self.send('ok')

    def on_line(self, line: str, now: float) -> None:
        with self._state_lock:
            if line == '$H':
                self.state = 'Home'
                self._homing_done = now + self.homing_time
                return  # 'ok' when the cycle completes
            if line == '$X':
                self.state = 'Idle'
                self.send('[MSG:Caution: Unlocked]')
                self.send('ok')
                return
            if line == '$$':
                for i, s in enumerate(self.specs):
                    self.send(f'$11{i}={s.max_rate:.3f}')
                    self.send(f'$12{i}={s.acceleration:.3f}')
                    self.send(f'$13{i}={s.travel:.3f}')
                self.send('ok')
                return
            if line.startswith('$J=') or line.startswith('G'):
                self._motion(line, now)
                return
            self.send('error:3' if line.startswith('$') else 'error:20')

    def _motion(self, line: str, now: float) -> None:
        if self.state == 'Alarm':
            self.send('error:9')
            return
        if self._held:
            self.send('error:8')  # a jog only in Idle or Jog
            return
        body = line[3:] if line.startswith('$J=') else line
        machine = 'G53' in body
        words = (
            body.replace('G53', ' ').replace('G90', ' ').replace('G1', ' ').replace('G0', ' ')
        ).split()
        try:
            values = {w[0]: float(w[1:]) for w in words}
        except (ValueError, IndexError):
            self.send('error:2')
            return
        feed = values.pop('F', None)
        if feed is None or feed <= 0:
            self.send('error:22')
            return
        if not machine:  # work coordinates: the machine position minus the work offset
            for i, axis in enumerate(self.specs):
                if axis.letter in values:
                    values[axis.letter] += self.work_offset[i]
        for letter, target in values.items():
            spec = next((s for s in self.specs if s.letter == letter), None)
            if spec is None:
                self.send('error:20')
                return
            if not 0.0 <= target <= spec.travel:
                self.send('error:15')  # soft limits: the jog is refused
                return
        # A jog of several axes is one straight line at the feed along it (GRBL's planner).
        deltas = {k: abs(v - self.sims[k].state(now)[0]) for k, v in values.items()}
        length = math.sqrt(sum(d * d for d in deltas.values()))
        for letter, target in values.items():
            share = deltas[letter] / length if length > 0.0 and len(values) > 1 else 1.0
            self.sims[letter].command(now, target, max(feed / 60.0 * share, 1e-6))
        self._held = False
        self.send('ok')
