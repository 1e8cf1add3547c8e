"""Reliability: a recorder killed by SIGKILL leaves a bag readable up to its last flush (8.6).

A publisher in this process sends numbered messages at 50 Hz; the recorder runs as its own
process (the real console script) and is killed with SIGKILL mid-stream. ``activesurv bag
reindex`` must then recover a gap-free prefix of the stream that misses at most the messages
of the last flush period (plus discovery start-up at the front), and the rebuilt bag must open
with rosbags like any other.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from activesurv_bringup.errors import BagError
from activesurv_recording.bagio import read_bag
from activesurv_recording.salvage import needs_reindex, reindex, scan_mcap

BIN = Path(sys.executable).parent
RATE = 50.0
FLUSH = 0.5


@pytest.mark.graph
def test_sigkill_loses_at_most_one_flush_period(tmp_path: Path, rclpy_context: Any) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    bag = tmp_path / 'bag'
    rec = subprocess.Popen(
        [
            str(BIN / 'recorder'),
            '--ros-args',
            '-p',
            f'output:={bag}',
            '-p',
            f'flush_period:={FLUSH}',
            '-p',
            'discovery_period:=0.2',
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    node = Node('numbered_publisher')
    pub = node.create_publisher(
        String, '/numbers', QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    )
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    try:
        deadline = time.monotonic() + 30.0
        while pub.get_subscription_count() == 0:  # the recorder has found the topic
            assert time.monotonic() < deadline, 'recorder never subscribed'
            assert rec.poll() is None, rec.stdout.read().decode() if rec.stdout else ''
            ex.spin_once(timeout_sec=0.05)
        sent = 0
        t0 = time.monotonic()
        while time.monotonic() - t0 < 3.0:
            pub.publish(String(data=json.dumps({'n': sent})))
            sent += 1
            ex.spin_once(timeout_sec=1.0 / RATE)
        t_kill = time.monotonic()
        os.kill(rec.pid, signal.SIGKILL)
        rec.wait(10)
    finally:
        ex.remove_node(node)
        node.destroy_node()
        if rec.poll() is None:
            rec.kill()
    rate = sent / (t_kill - t0)

    assert needs_reindex(bag)
    with pytest.raises(BagError, match='reindex'):
        list(read_bag(bag))
    scan = scan_mcap(next(bag.glob('*.mcap')))
    assert not scan.complete

    report = reindex(bag)
    assert report.damaged.exists()
    numbers = [json.loads(m.msg.data)['n'] for m in read_bag(bag, {'/numbers'})]
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers))), 'a gap in the stream'
    lost_at_end = sent - 1 - numbers[-1]
    # At most one flush period, with one period of slack for a busy machine's timer jitter.
    assert lost_at_end <= rate * 2 * FLUSH + 5, (lost_at_end, rate)
    assert len(numbers) >= sent - numbers[0] - rate * 2 * FLUSH - 5
    assert report.messages >= len(numbers)
    assert '/activesurv/run_info' in {m.topic for m in read_bag(bag)}


@pytest.mark.cli
def test_reindex_errors_are_clear(tmp_path: Path) -> None:
    with pytest.raises(BagError, match=r'no \.mcap'):
        reindex(tmp_path)
    (tmp_path / 'b').mkdir()
    (tmp_path / 'b' / 'b.mcap').write_bytes(b'not an mcap file')
    with pytest.raises(BagError, match='not an MCAP'):
        reindex(tmp_path / 'b')
    (tmp_path / 'b' / 'b.mcap').write_bytes(b'\x89MCAP0\r\n\x01\xff')
    with pytest.raises(BagError, match='no complete message'):
        reindex(tmp_path / 'b')
    assert (tmp_path / 'b' / 'b.mcap').exists(), 'the original is kept'
    r = subprocess.run(
        [str(BIN / 'activesurv'), 'bag', 'reindex', str(tmp_path / 'b')],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 1
    assert 'no complete message' in r.stderr
    assert 'Traceback' not in r.stderr


@pytest.mark.graph
def test_a_full_disk_stops_the_recorder_with_its_reason(
    tmp_path: Path, rclpy_context: Any
) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    small = tmp_path / 'small'
    small.mkdir()
    mounted = subprocess.run(
        ['mount', '-t', 'tmpfs', '-o', 'size=1m', 'tmpfs', str(small)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f'cannot mount a small tmpfs here: {mounted.stderr.decode().strip()}')
    rec = subprocess.Popen(
        [str(BIN / 'recorder'), '--ros-args', '-p', f'output:={small / "bag"}',
         '-p', 'flush_period:=0.2', '-p', 'discovery_period:=0.2'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    node = Node('filler')
    pub = node.create_publisher(
        String, '/filler', QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    )
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    try:
        deadline = time.monotonic() + 30.0
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, 'recorder never subscribed'
            ex.spin_once(timeout_sec=0.05)
        block = 'x' * 20_000  # 1 MB fills in about 50 messages
        while rec.poll() is None and time.monotonic() < deadline + 30.0:
            pub.publish(String(data=block))
            ex.spin_once(timeout_sec=0.01)
        out = rec.communicate(timeout=10)[0]
    finally:
        ex.remove_node(node)
        node.destroy_node()
        if rec.poll() is None:
            rec.kill()
        subprocess.run(['umount', '-l', str(small)], capture_output=True)
    assert rec.returncode != 0
    assert 'disk full' in out
