"""GRBL 1.1 serial protocol: line classification, status reports, commands (pure).

Every line sent is answered with ``ok`` or ``error:N``. Real-time commands are single bytes
with no newline and no ``ok``: ``?`` status report, ``!`` feed hold, ``~`` cycle start,
0x85 jog cancel, 0x18 soft reset. A status report looks like
``<Idle|MPos:0.000,0.000,0.000|FS:0,0>``; states are Idle, Run, Hold:N, Jog, Alarm, Door:N,
Check, Home, Sleep. ``ALARM:N`` lines announce an alarm (position may be lost); after a reset
with homing enabled the controller starts in Alarm and asks for ``$H`` (home) or ``$X``.
Positions are machine units (mm, or degrees for a rotary axis); feed rates are units/min.

Jogs are sent in machine coordinates (``$J=G53 ...``): the positions read back are the status
report's ``MPos`` (or ``WPos`` + ``WCO`` when ``$10`` asks for work positions), so a work
offset some other program left (G10, G92) never shifts where the stage goes. A jog is stopped
with the jog cancel (0x85) alone: GRBL's jogging notes warn that a feed hold sent once the jog
has ended suspends the controller (``Hold:0``, every later jog refused with error 8).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from activesurv_stages.errors import ProtocolError

STATUS_QUERY = b'?'
FEED_HOLD = b'!'
CYCLE_START = b'~'
JOG_CANCEL = b'\x85'
SOFT_RESET = b'\x18'

ERRORS = {
    1: 'G-code words consist of a letter and a value; letter was not found',
    2: 'numeric value format is not valid or missing an expected value',
    3: "grbl '$' system command was not recognized or supported",
    8: "grbl '$' command cannot be used unless grbl is idle",
    9: 'G-code locked out during alarm or jog state',
    15: 'jog target exceeds machine travel; command ignored',
    16: "jog command with no '=' or contains prohibited g-code",
    20: 'unsupported or invalid g-code command found in block',
    22: 'feed rate has not yet been set or is undefined',
}
ALARMS = {
    1: 'hard limit triggered; position lost, re-home',
    2: 'soft limit: motion target exceeds machine travel',
    3: 'reset while in motion; position lost, re-home',
    6: 'homing fail: reset during active homing cycle',
    8: 'homing fail: pull-off did not clear the limit switch',
    9: 'homing fail: could not find the limit switch',
}

_STATUS = re.compile(r'^<(?P<state>[A-Za-z]+)(?::(?P<sub>\d))?\|(?P<fields>[^>]*)>$')
_BANNER = re.compile(r"^Grbl (?P<version>\S+) \['\$' for help\]$")


@dataclass(frozen=True)
class Status:
    """A parsed status report."""

    state: str
    substate: int | None
    mpos: tuple[float, ...]  # machine positions (None-free: WPos + WCO when $10 says WPos)
    feed: float
    wco: tuple[float, ...] | None = None  # the work coordinate offset, when reported

    @property
    def busy(self) -> bool:
        return self.state in ('Run', 'Jog', 'Home', 'Hold')

    @property
    def alarm(self) -> bool:
        return self.state == 'Alarm'


def parse_status(line: str, wco: tuple[float, ...] | None = None) -> Status:
    """Parse ``<State|MPos:...|FS:...>`` (fields in any order, unknown ones ignored: ``Bf``,
    ``Ln``, ``Pn``, ``Ov``, ``A``). A report in work positions (``WPos``: ``$10=0``) is turned
    into machine positions with its ``WCO``, or the last one reported (``wco``: GRBL sends it
    only every 10-30 reports).

    Raises:
        ProtocolError: if the line is not a status report, or has work positions and no
            offset is known yet.
    """
    m = _STATUS.match(line.strip())
    if not m:
        raise ProtocolError(f'not a GRBL status report: {line!r}')
    fields = dict(f.split(':', 1) for f in m['fields'].split('|') if ':' in f)
    try:
        offset = tuple(float(v) for v in fields['WCO'].split(',')) if 'WCO' in fields else wco
        feed = float(fields.get('FS', fields.get('F', '0')).split(',')[0])
        if 'MPos' in fields:
            pos = tuple(float(v) for v in fields['MPos'].split(','))
        elif 'WPos' in fields:
            work = tuple(float(v) for v in fields['WPos'].split(','))
            if offset is None or len(offset) != len(work):
                raise ProtocolError(
                    f'GRBL reports work positions ($10=0) and no WCO yet: {line!r} '
                    '(set $10=1 for machine positions)'
                )
            pos = tuple(w + o for w, o in zip(work, offset, strict=True))
        else:
            pos = ()
    except ValueError as exc:
        raise ProtocolError(f'malformed GRBL status report: {line!r}') from exc
    if not pos:
        raise ProtocolError(f'GRBL status report without a position: {line!r}')
    return Status(m['state'], int(m['sub']) if m['sub'] else None, pos, feed, offset)


def classify(line: str) -> tuple[str, str]:
    """Kind of a line from GRBL: ok, error, alarm, status, banner, message, setting, or other.

    Returns:
        (kind, payload): payload is the error/alarm number, the message text, etc.
    """
    text = line.strip()
    if text == 'ok':
        return 'ok', ''
    if text.startswith('error:'):
        return 'error', text[6:]
    if text.startswith('ALARM:'):
        return 'alarm', text[6:]
    if text.startswith('<') and text.endswith('>'):
        return 'status', text
    if _BANNER.match(text):
        return 'banner', text
    if text.startswith('[') and text.endswith(']'):
        return 'message', text[1:-1]
    if re.match(r'^\$\d+=', text):
        return 'setting', text
    return 'other', text


def error_text(code: str) -> str:
    try:
        return f'error:{code} ({ERRORS.get(int(code), "unknown error")})'
    except ValueError:
        return f'error:{code}'


def alarm_text(code: str) -> str:
    try:
        return f'ALARM:{code} ({ALARMS.get(int(code), "unknown alarm")})'
    except ValueError:
        return f'ALARM:{code}'


def format_jog(axis: str, position: float, feed_per_min: float) -> bytes:
    """An absolute jog in machine coordinates (cancellable with 0x85):
    ``$J=G53 X10.0000 F600.000``.

    Raises:
        ProtocolError: for an unknown axis letter or a non-positive feed.
    """
    if axis not in 'XYZABC' or len(axis) != 1:
        raise ProtocolError(f'unknown GRBL axis {axis!r}')
    if not feed_per_min > 0:
        raise ProtocolError(f'feed rate must be > 0, got {feed_per_min}')
    return f'$J=G53 {axis}{position:.4f} F{feed_per_min:.3f}\n'.encode('ascii')


def format_jog_together(targets: dict[str, float], feed_per_min: float) -> bytes:
    """One absolute jog of several axes along a straight line (GRBL coordinates them; the
    feed is the speed along the line), in machine coordinates:
    ``$J=G53 X10.0000 Y5.0000 F600.000``.

    Raises:
        ProtocolError: for an unknown axis letter, no axis, or a non-positive feed.
    """
    if not targets or any(a not in 'XYZABC' or len(a) != 1 for a in targets):
        raise ProtocolError(f'unknown or no GRBL axes {sorted(targets)}')
    if not feed_per_min > 0:
        raise ProtocolError(f'feed rate must be > 0, got {feed_per_min}')
    words = ' '.join(f'{a}{v:.4f}' for a, v in targets.items())
    return f'$J=G53 {words} F{feed_per_min:.3f}\n'.encode('ascii')
