"""Bags split by duration: bag_0.mcap, bag_1.mcap, ... in one metadata.yaml, readable by rosbags
and by Foxglove's MCAP readers, each file replaying on its own (no ROS graph)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from activesurv_recording.bagio import SplitBagWriter, read_bag
from activesurv_recording.errors import BagError


def _string(w: SplitBagWriter, topic: str, t: float, text: str) -> None:
    msg = w.ts.types['std_msgs/msg/String'](data=text)
    w.write_raw(
        topic,
        'std_msgs/msg/String',
        int(t * 1e9),
        bytes(w.ts.serialize_cdr(msg, 'std_msgs/msg/String')),
    )


def test_split_bag_files_metadata_and_readers(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    w = SplitBagWriter(bag, max_duration=2.0, latched={'/plan'})
    w.write_json('/activesurv/run_info', 0, {'mode': 'test'})
    _string(w, '/plan', 0.05, 'plan 0')
    for k in range(50):  # 5 s at 10 Hz
        _string(w, '/chatter', 0.1 * k, f'm{k}')
    _string(w, '/late', 4.95, 'a topic that appears late')
    w.close()
    files = sorted(p.name for p in bag.glob('*.mcap'))
    assert files == ['bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap']
    assert not list(bag.glob('.split_*')), 'no hidden work directory is left behind'
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['relative_file_paths'] == files
    assert [f['path'] for f in meta['files']] == files
    counts = {
        t['topic_metadata']['name']: t['message_count'] for t in meta['topics_with_message_count']
    }
    assert counts['/chatter'] == 50
    # rosbags reads the whole split bag, in time order.
    chatter = [m.msg.data for m in read_bag(bag, {'/chatter'})]
    assert chatter == [f'm{k}' for k in range(50)]
    # Every file repeats the latched plan and the run information: it replays on its own.
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    for name in files:
        with open(bag / name, 'rb') as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            seen = {ch.topic for _, ch, _, _ in reader.iter_decoded_messages()}
        assert {'/plan', '/activesurv/run_info', '/chatter'} <= seen, name


def test_a_split_bag_refuses_an_existing_directory_and_a_zero_duration(tmp_path: Path) -> None:
    (tmp_path / 'bag').mkdir()
    with pytest.raises(BagError):
        SplitBagWriter(tmp_path / 'bag', 1.0)
    with pytest.raises(BagError):
        SplitBagWriter(tmp_path / 'other', 0.0)


def test_keep_bags_deletes_the_oldest_files_and_the_rest_reads(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    w = SplitBagWriter(bag, max_duration=1.0, latched={'/plan'}, keep=2)
    w.write_json('/activesurv/run_info', 0, {'mode': 'test'})
    _string(w, '/plan', 0.05, 'plan 0')
    for k in range(50):  # 5 s at 10 Hz: five files, the newest two kept
        _string(w, '/chatter', 0.1 * k, f'm{k}')
    w.close()
    files = sorted(p.name for p in bag.glob('*.mcap'))
    assert files == ['bag_3.mcap', 'bag_4.mcap']
    assert w.removed == ['bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap']
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['relative_file_paths'] == files
    chatter = [m.msg.data for m in read_bag(bag, {'/chatter'})]
    assert chatter == [f'm{k}' for k in range(30, 50)]
    assert next(m.msg.data for m in read_bag(bag, {'/plan'})) == 'plan 0'  # latched: repeated


def test_a_size_limit_splits_the_bag(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    w = SplitBagWriter(bag, max_duration=0.0, max_bytes=20_000)
    w.write_json('/activesurv/run_info', 0, {'mode': 'test'})
    for k in range(200):
        _string(w, '/chatter', 0.01 * k, 'x' * 500)
        if k % 20 == 19:
            w.flush()  # the recorder flushes every 0.5 s; the size is checked then
    w.close()
    files = sorted(bag.glob('*.mcap'))
    assert len(files) >= 3
    chatter = list(read_bag(bag, {'/chatter'}))
    assert len(chatter) == 200
