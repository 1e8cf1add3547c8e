"""Zaber ASCII protocol: command formatting and reply parsing (pure).

Commands: ``/<device> <axis> <command> [data]`` terminated by a newline; device 0 addresses
every device on the daisy chain, axis 0 the whole device. Replies::

    @01 0 OK IDLE -- 12345        reply: device, axis, flag (OK/RJ), status, warning, data
    !01 0 IDLE --                 alert (unsolicited)
    #01 0 some info               info line

The warning field is ``--`` or the most severe flag: F* faults (FS stalled and stopped,
FD driver disabled, ...), W* warnings (WR no reference position, WH not homed, WL unexpected
limit trigger, ...), N* notices (NI command interrupted, ...). A rejected command (RJ) gives the
reason as data: BADCOMMAND, BADDATA, BADAXIS, AGAIN, ...
Devices reply with ``\\r\\n``; an optional ``:CC`` checksum may end a message.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from activesurv_stages.errors import ProtocolError

# Speed settings are in microsteps per 1/1.6384 s (Zaber's "data" speed unit).
SPEED_UNIT = 1.6384

NOT_HOMED = frozenset({'WR', 'WH'})

_REPLY = re.compile(
    r'^@(?P<device>\d{2}) (?P<axis>\d+)(?: (?P<id>\d+))? (?P<flag>OK|RJ) '
    r'(?P<status>IDLE|BUSY) (?P<warning>--|[A-Z]{2}) ?(?P<data>.*?)(?::[0-9A-F]{2})?$'
)
_ALERT = re.compile(
    r'^!(?P<device>\d{2}) (?P<axis>\d+) (?P<status>IDLE|BUSY) '
    r'(?P<warning>--|[A-Z]{2})(?: (?P<data>.*))?$'
)


@dataclass(frozen=True)
class Reply:
    """A parsed ``@`` reply."""

    device: int
    axis: int
    flag: str
    status: str
    warning: str
    data: str
    message_id: int | None = None

    @property
    def ok(self) -> bool:
        return self.flag == 'OK'

    @property
    def busy(self) -> bool:
        return self.status == 'BUSY'

    @property
    def fault(self) -> bool:
        return self.warning.startswith('F')

    @property
    def not_homed(self) -> bool:
        return self.warning in NOT_HOMED


@dataclass(frozen=True)
class Alert:
    device: int
    axis: int
    status: str
    warning: str


def format_command(
    device: int, command: str, axis: int = 0, message_id: int | None = None
) -> bytes:
    """``/device axis [id] command\\n`` as bytes; the id (0..99) is echoed in the reply.

    Raises:
        ProtocolError: for a device number outside 0..99 or a command with a line break.
    """
    if not 0 <= device <= 99 or not 0 <= axis <= 9:
        raise ProtocolError(f'Zaber device must be 0..99 and axis 0..9, got {device}, {axis}')
    if message_id is not None and not 0 <= message_id <= 99:
        raise ProtocolError(f'Zaber message id must be 0..99, got {message_id}')
    if '\n' in command or '\r' in command or '/' in command:
        raise ProtocolError(f'invalid characters in Zaber command {command!r}')
    mid = '' if message_id is None else f' {message_id}'
    text = f'/{device} {axis}{mid} {command}'.rstrip()
    return (text + '\n').encode('ascii')


def parse_line(line: str) -> Reply | Alert | str:
    """Parse one line: a :class:`Reply`, an :class:`Alert`, or the text of an info line.

    Raises:
        ProtocolError: if the line is not a Zaber message (garbage on the wire).
    """
    text = line.strip()
    m = _REPLY.match(text)
    if m:
        return Reply(
            int(m['device']),
            int(m['axis']),
            m['flag'],
            m['status'],
            m['warning'],
            m['data'].strip(),
            int(m['id']) if m['id'] else None,
        )
    m = _ALERT.match(text)
    if m:
        return Alert(int(m['device']), int(m['axis']), m['status'], m['warning'])
    if text.startswith('#') and len(text) >= 3 and text[1:3].isdigit():
        return text
    raise ProtocolError(f'not a Zaber message: {line!r}')


def speed_to_data(steps_per_second: float) -> int:
    """Speed in microsteps/s to Zaber's ``maxspeed`` data value (at least 1)."""
    return max(1, round(steps_per_second * SPEED_UNIT))


def data_to_speed(data: int) -> float:
    return data / SPEED_UNIT
