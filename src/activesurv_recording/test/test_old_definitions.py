"""A bag is read with the message definitions stored in it: a run recorded before a message
gained fields (MarkerObservation.compute_time, frame_received and published, its last) still
reads, and reports render."""

from __future__ import annotations

from pathlib import Path

from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from activesurv_interfaces.msg import MarkerObservation
from activesurv_recording.bagio import interface_dir, read_bag

TYPE = 'activesurv_interfaces/msg/MarkerObservation'


def test_a_bag_with_an_older_definition_reads_as_written(tmp_path: Path) -> None:
    d = interface_dir()
    older = '\n'.join(
        line
        for line in (d / 'MarkerObservation.msg').read_text().splitlines()
        if not line.startswith(
            ('float64 compute_time', 'float64 frame_received', 'float64 published')
        )
        and not line.lstrip().startswith('# (the imager')
    )
    ts = get_typestore(Stores.ROS2_JAZZY)
    types = get_types_from_msg(older, TYPE)
    types.update(
        get_types_from_msg((d / 'Ellipse.msg').read_text(), 'activesurv_interfaces/msg/Ellipse')
    )
    ts.register(types)
    msg = MarkerObservation(camera_id='cam2', demand_index=7, compute_time=0.004)
    raw = serialize_message(msg)[:-24]  # the old layout: without its last three float64
    bag = tmp_path / 'old'
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conn = writer.add_connection('/marker_observations', TYPE, typestore=ts)
    writer.write(conn, 1_000, raw)
    writer.close()
    (m,) = list(read_bag(bag, {'/marker_observations'}))
    assert (m.msg.camera_id, m.msg.demand_index) == ('cam2', 7)
    assert not hasattr(m.msg, 'compute_time')  # read as it was written
    assert not hasattr(m.msg, 'frame_received')
    assert not hasattr(m.msg, 'published')
