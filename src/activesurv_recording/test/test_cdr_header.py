"""The raw readers take a message's stamp and frame_id straight from its CDR bytes."""

from __future__ import annotations

import pytest
from rclpy.serialization import serialize_message


def test_cdr_header_reads_stamp_and_frame_id() -> None:
    from sensor_msgs.msg import Image

    from activesurv_recording.bagio import cdr_header

    msg = Image(height=2, width=3, encoding='rgb8', step=9, data=bytes(18))
    msg.header.stamp.sec = 1795236220
    msg.header.stamp.nanosec = 250_000_000
    msg.header.frame_id = 'cam3:41'
    assert cdr_header(serialize_message(msg)) == (pytest.approx(1795236220.25), 'cam3:41')
    with pytest.raises(ValueError, match='CDR'):
        cdr_header(b'\x00\x01\x00\x00' + bytes(4))
    with pytest.raises(ValueError, match='frame_id'):
        cdr_header(b'\x00\x01\x00\x00' + bytes(8) + b'\xff\xff\x00\x00' + bytes(4))
