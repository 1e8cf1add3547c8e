"""Serial drivers for the motion controllers, behind the :class:`StageDriver` protocol.

Drivers speak raw controller units: Zaber microsteps (speeds in microsteps/s), GRBL machine
units (mm or degrees; speeds in units/s). Conversion to SI and the soft-limit check happen a layer
up (:mod:`activesurv_stages.bridge`), before a driver is asked to write anything.

Errors: a missing or unplugged port, or silence past the timeout, raise
:class:`CommunicationError`; a refusal raises :class:`ControllerRejectedError`. A line of
garbage is skipped and counted: the request still succeeds if its reply follows.
"""

from __future__ import annotations

import contextlib
import os
import termios
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import serial

from activesurv_stages.errors import (
    CommunicationError,
    ControllerRejectedError,
    ProtocolError,
    StageError,
)
from activesurv_stages.protocols import grbl, zaber


@dataclass(frozen=True)
class AxisReport:
    """One axis as the controller reports it.

    Attributes:
        axis: controller axis id (Zaber device number "1", "2"...; GRBL letter "X", "A"...).
        position: raw units.
        status: "idle", "busy" or "fault".
        needs_home: the controller has no reference position (homing lost).
        detail: warning flag or state text.
    """

    axis: str
    position: float
    status: str
    needs_home: bool = False
    detail: str = ''


class StageDriver(Protocol):
    """What the bridge needs from a motion controller."""

    protocol: str
    garbage_lines: int

    def connect(self) -> list[str]:
        """Open the port, find the axes; returns their ids."""
        ...

    def close(self) -> None: ...

    def poll(self) -> list[AxisReport]: ...

    def home(self, axis: str) -> None: ...

    def move(self, axis: str, position: float, speed: float | None) -> None:
        """Absolute move in raw units; ``speed`` in raw units/s (None: the controller's)."""
        ...

    def stop(self, axis: str) -> None: ...


class SerialLine:
    """A pyserial port with line reads against a deadline and errors as StageErrors."""

    def __init__(self, port: str, baud: int, timeout: float) -> None:
        if not os.path.exists(port):
            raise CommunicationError(f'serial port {port} does not exist (unplugged?)')
        try:
            self.ser = serial.Serial(port, baud, timeout=0.05, write_timeout=timeout)
        except (serial.SerialException, OSError, termios.error) as exc:
            raise CommunicationError(f'cannot open {port}: {exc}') from exc
        self.port = port
        self.timeout = timeout

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.ser.close()

    def write(self, data: bytes) -> None:
        # No flush(): tcdrain() can block forever on a vanished device; the write timeout
        # bounds the write itself.
        try:
            self.ser.write(data)
        except (serial.SerialException, OSError, termios.error) as exc:
            raise CommunicationError(f'write to {self.port} failed: {exc}') from exc

    def flush_input(self) -> None:
        with contextlib.suppress(serial.SerialException, OSError, termios.error):
            self.ser.reset_input_buffer()

    def readline(self, deadline: float) -> str | None:
        """One line, or None at the deadline."""
        buf = b''
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            try:
                self.ser.timeout = min(remaining, 0.05)
                chunk: bytes = self.ser.read_until(b'\n')
            except (serial.SerialException, OSError, termios.error) as exc:
                raise CommunicationError(f'read from {self.port} failed: {exc}') from exc
            buf += chunk
            if buf.endswith(b'\n'):
                return buf.decode('ascii', errors='replace').strip('\r\n')


class ZaberDriver:
    """Zaber ASCII devices on one daisy chain; axis ids are device numbers."""

    protocol = 'zaber'

    def __init__(self, port: str, baud: int = 115200, timeout: float = 2.0) -> None:
        self.port, self.baud, self.timeout = port, baud, timeout
        self.line: SerialLine | None = None
        self.devices: list[int] = []
        self.garbage_lines = 0
        self._next_id = 0

    def connect(self) -> list[str]:
        self.close()
        self.line = SerialLine(self.port, self.baud, self.timeout)
        self.line.flush_input()
        self.line.write(zaber.format_command(0, ''))
        found: set[int] = set()
        deadline = time.monotonic() + self.timeout
        quiet_until = deadline
        while time.monotonic() < min(deadline, quiet_until):
            text = self.line.readline(min(deadline, quiet_until))
            if text is None:
                break
            try:
                msg = zaber.parse_line(text)
            except ProtocolError:
                self.garbage_lines += 1
                continue
            if isinstance(msg, zaber.Reply):
                found.add(msg.device)
                quiet_until = time.monotonic() + 0.2  # the chain answers in a burst
        if not found:
            self.close()
            raise CommunicationError(
                f'no Zaber device answered on {self.port} within {self.timeout:g} s'
            )
        self.devices = sorted(found)
        return [str(d) for d in self.devices]

    def close(self) -> None:
        if self.line is not None:
            self.line.close()
            self.line = None

    def _device(self, axis: str) -> int:
        try:
            n = int(axis)
        except ValueError as exc:
            raise StageError(f'Zaber axis ids are device numbers, got {axis!r}') from exc
        if self.devices and n not in self.devices:
            raise StageError(f'no Zaber device {n} on {self.port} (found {self.devices})')
        return n

    def request(self, device: int, command: str) -> zaber.Reply:
        """Send one command and return the device's reply to it (matched by message id)."""
        if self.line is None:
            raise CommunicationError(f'{self.port} is not connected')
        mid = self._next_id
        self._next_id = (self._next_id + 1) % 100
        self.line.write(zaber.format_command(device, command, message_id=mid))
        deadline = time.monotonic() + self.timeout
        while True:
            text = self.line.readline(deadline)
            if text is None:
                raise CommunicationError(
                    f'no reply from Zaber device {device} to {command!r} within {self.timeout:g} s'
                )
            try:
                msg = zaber.parse_line(text)
            except ProtocolError:
                self.garbage_lines += 1
                continue
            if (
                isinstance(msg, zaber.Reply)
                and msg.device == device
                and (msg.message_id in (None, mid))
            ):
                return msg

    def _checked(self, device: int, command: str) -> zaber.Reply:
        r = self.request(device, command)
        if not r.ok:
            raise ControllerRejectedError(
                f'Zaber device {device} rejected {command!r}: {r.data or "no reason"} '
                f'(warning {r.warning})'
            )
        return r

    def poll(self) -> list[AxisReport]:
        out = []
        for d in self.devices:
            r = self.request(d, 'get pos')
            try:
                pos = float(r.data)
            except ValueError as exc:
                raise ProtocolError(f'device {d} sent a non-numeric position {r.data!r}') from exc
            status = 'fault' if r.fault else ('busy' if r.busy else 'idle')
            out.append(AxisReport(str(d), pos, status, r.not_homed, r.warning))
        return out

    def home(self, axis: str) -> None:
        self._checked(self._device(axis), 'home')

    def move(self, axis: str, position: float, speed: float | None) -> None:
        d = self._device(axis)
        if speed is not None:
            self._checked(d, f'set maxspeed {zaber.speed_to_data(speed)}')
        self._checked(d, f'move abs {round(position)}')

    def stop(self, axis: str) -> None:
        """Zaber ASCII ``stop``: the device decelerates at its own rate and holds."""
        self._checked(self._device(axis), 'stop')


class GrblDriver:
    """A GRBL controller; axis ids are the letters of its status report (X, Y, Z, A)."""

    protocol = 'grbl'
    LETTERS = 'XYZABC'

    def __init__(
        self, port: str, baud: int = 115200, timeout: float = 2.0, homing_timeout: float = 60.0
    ) -> None:
        self.port, self.baud, self.timeout = port, baud, timeout
        self.homing_timeout = homing_timeout
        self.line: SerialLine | None = None
        self.letters: list[str] = []
        self.garbage_lines = 0
        self.alarms: list[str] = []
        self.wco: tuple[float, ...] | None = None  # the last work offset reported

    def connect(self) -> list[str]:
        self.close()
        self.wco = None
        self.line = SerialLine(self.port, self.baud, self.timeout)
        self.line.write(b'\r\n')
        try:
            status = self.status()
        except CommunicationError as exc:
            self.close()
            raise CommunicationError(
                f'no GRBL status report on {self.port} within {self.timeout:g} s'
            ) from exc
        self.line.flush_input()  # the 'ok' or error of the wake-up line
        self.letters = list(self.LETTERS[: len(status.mpos)])
        return list(self.letters)

    def close(self) -> None:
        if self.line is not None:
            self.line.close()
            self.line = None

    def _line(self) -> SerialLine:
        if self.line is None:
            raise CommunicationError(f'{self.port} is not connected')
        return self.line

    def status(self) -> grbl.Status:
        line = self._line()
        line.write(grbl.STATUS_QUERY)
        deadline = time.monotonic() + self.timeout
        while True:
            text = line.readline(deadline)
            if text is None:
                raise CommunicationError(f'no GRBL status report within {self.timeout:g} s')
            kind, payload = grbl.classify(text)
            if kind == 'status':
                try:
                    st = grbl.parse_status(payload, self.wco)
                except ProtocolError:
                    self.garbage_lines += 1
                    if 'WPos' in payload and 'WCO' not in payload and self.wco is None:
                        raise  # work positions with no offset yet: say so, not "no report"
                    continue
                self.wco = st.wco
                return st
            elif kind == 'alarm':
                self.alarms.append(grbl.alarm_text(payload))
            elif kind == 'other':
                self.garbage_lines += 1

    def command(self, text: str, timeout: float | None = None) -> None:
        line = self._line()
        line.write(text.encode('ascii') + (b'' if text.endswith('\n') else b'\n'))
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            reply = line.readline(deadline)
            if reply is None:
                line.flush_input()  # a late 'ok' must not answer the next command
                raise CommunicationError(f'no GRBL reply to {text.strip()!r} in time')
            kind, payload = grbl.classify(reply)
            if kind == 'ok':
                return
            if kind == 'error':
                raise ControllerRejectedError(
                    f'GRBL rejected {text.strip()!r}: {grbl.error_text(payload)}'
                )
            if kind == 'alarm':
                self.alarms.append(grbl.alarm_text(payload))
                raise ControllerRejectedError(
                    f'GRBL alarm during {text.strip()!r}: {grbl.alarm_text(payload)}'
                )
            if kind == 'other':
                self.garbage_lines += 1

    def poll(self) -> list[AxisReport]:
        st = self.status()
        # Hold:0 is a feed hold complete: nothing moves, and GRBL refuses every jog (error 8)
        # until a cycle start; something other than this driver held it (a pendant, a sender).
        held = st.state == 'Hold' and st.substate == 0
        status = 'fault' if st.alarm or held else ('busy' if st.busy else 'idle')
        detail = (
            'Hold:0 (a feed hold is pending: resume with ~ once nothing else is queued)'
            if held
            else st.state
        )
        return [
            AxisReport(letter, st.mpos[i], status, st.alarm, detail)
            for i, letter in enumerate(self.letters)
        ]

    def home(self, axis: str) -> None:
        self.command('$H', timeout=self.homing_timeout)  # GRBL homes all axes together

    def move(self, axis: str, position: float, speed: float | None) -> None:
        if axis not in self.letters:
            raise StageError(f'no GRBL axis {axis!r} (found {self.letters})')
        feed = 60.0 * (speed if speed is not None else 1000.0)
        self.command(grbl.format_jog(axis, position, feed).decode())

    def move_together(self, targets: dict[str, float], speed: float | None) -> None:
        """Move several axes along one straight line at ``speed`` (units/s along it)."""
        unknown = [a for a in targets if a not in self.letters]
        if unknown:
            raise StageError(f'no GRBL axes {unknown} (found {self.letters})')
        feed = 60.0 * (speed if speed is not None else 1000.0)
        self.command(grbl.format_jog_together(targets, feed).decode())

    def stop(self, axis: str) -> None:
        """Stop the whole machine (GRBL has one planner). First the jog cancel (0x85: a jog,
        ours, decelerates, every queued jog is flushed, back to Idle; at rest it does nothing);
        then, by what the status says: a G-code cycle someone else started gets a feed hold, a
        homing cycle a soft reset (the only way to stop it; GRBL then asks for homing again).
        Never a feed hold at rest: GRBL would suspend (Hold:0) and refuse every later jog."""
        line = self._line()
        line.write(grbl.JOG_CANCEL)
        try:
            state = self.status().state
        except (CommunicationError, ProtocolError):
            return  # the cancel is sent; nothing more can be known
        if state == 'Run':
            line.write(grbl.FEED_HOLD)
        elif state == 'Home':
            line.write(grbl.SOFT_RESET)


DriverFactory = Callable[..., Any]
DRIVERS: dict[str, DriverFactory] = {'zaber': ZaberDriver, 'grbl': GrblDriver}


def make_driver(protocol: str, port: str, baud: int = 115200, timeout: float = 2.0) -> StageDriver:
    """A driver from the registry.

    Raises:
        StageError: for an unknown protocol.
    """
    try:
        factory = DRIVERS[protocol]
    except KeyError as exc:
        raise StageError(f'unknown protocol {protocol!r}; choose from {sorted(DRIVERS)}') from exc
    driver: StageDriver = factory(port, baud, timeout)
    return driver
