"""Zaber ASCII and GRBL wire formats (no serial port)."""

from __future__ import annotations

import pytest

from activesurv_stages.errors import ProtocolError
from activesurv_stages.protocols import grbl, zaber


def test_zaber_format_and_parse() -> None:
    assert zaber.format_command(1, 'move abs 10000') == b'/1 0 move abs 10000\n'
    assert zaber.format_command(2, 'get pos', message_id=7) == b'/2 0 7 get pos\n'
    r = zaber.parse_line('@01 0 OK IDLE -- 12345')
    assert isinstance(r, zaber.Reply)
    assert (r.device, r.ok, r.busy, r.warning, r.data) == (1, True, False, '--', '12345')
    r = zaber.parse_line('@02 0 42 RJ BUSY WR BADDATA\r\n')
    assert isinstance(r, zaber.Reply)
    assert (r.message_id, r.ok, r.busy, r.not_homed, r.data) == (42, False, True, True, 'BADDATA')
    r = zaber.parse_line('@01 0 OK IDLE FS 0:7A')
    assert isinstance(r, zaber.Reply)
    assert r.fault
    assert r.data == '0'
    assert isinstance(zaber.parse_line('!01 0 IDLE --'), zaber.Alert)
    assert zaber.parse_line('#01 0 some info') == '#01 0 some info'
    for junk in ('', 'ok', '@1 0 OK IDLE -- 0', '\x8f\x12garbage'):
        with pytest.raises(ProtocolError):
            zaber.parse_line(junk)
    with pytest.raises(ProtocolError):
        zaber.format_command(100, 'home')
    with pytest.raises(ProtocolError):
        zaber.format_command(1, 'home\n/2 stop')
    assert zaber.speed_to_data(1000.0) == 1638


def test_grbl_classify_and_status() -> None:
    assert grbl.classify('ok') == ('ok', '')
    assert grbl.classify('error:9') == ('error', '9')
    assert grbl.classify('ALARM:3') == ('alarm', '3')
    assert grbl.classify("Grbl 1.1h ['$' for help]")[0] == 'banner'
    assert grbl.classify('[MSG:Caution: Unlocked]') == ('message', 'MSG:Caution: Unlocked')
    assert grbl.classify('$110=500.000')[0] == 'setting'
    s = grbl.parse_status('<Jog|MPos:10.000,-2.500,0.000,90.000|FS:600,0|Pn:X>')
    assert s.state == 'Jog'
    assert s.mpos == (10.0, -2.5, 0.0, 90.0)
    assert s.busy
    assert grbl.parse_status('<Hold:1|MPos:0,0,0|FS:0,0>').substate == 1
    assert grbl.parse_status('<Alarm|MPos:0,0,0|FS:0,0>').alarm
    for junk in ('<Idle>', '<Idle|MPos:a,b|FS:0,0>', 'Idle|MPos:0,0,0'):
        with pytest.raises(ProtocolError):
            grbl.parse_status(junk)
    assert 'soft limit' in grbl.alarm_text('2')
    assert grbl.format_jog('A', 90.0, 600.0) == b'$J=G53 A90.0000 F600.000\n'  # machine frame
    # $10=0: work positions, turned into machine positions with the (occasional) WCO.
    w = grbl.parse_status('<Idle|WPos:1.000,2.000|FS:0,0|WCO:10.000,-5.000|Ov:100,100,100>')
    assert w.mpos == (11.0, -3.0)
    assert w.wco == (10.0, -5.0)
    assert grbl.parse_status('<Idle|WPos:1.000,2.000|FS:0,0>', w.wco).mpos == (11.0, -3.0)
    with pytest.raises(ProtocolError, match=r'\$10=1'):
        grbl.parse_status('<Idle|WPos:1.000,2.000|FS:0,0>')
    with pytest.raises(ProtocolError):
        grbl.format_jog('Q', 1.0, 600.0)
