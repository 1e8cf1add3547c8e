"""``ACTIVESURV_CALLBACK_CPU``: each callback's CPU, written by the process when it stops."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from activesurv_common.ros import callback_cpu

# A process with a timer that burns CPU, a subscription (with message info: rclpy reads the
# callback's signature, the timing must keep it) and a publisher, as run_node sets one up.
PROBE = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from std_msgs.msg import String
    from activesurv_common.ros import callback_cpu
    rclpy.init()
    installed = callback_cpu.install()
    node = rclpy.create_node('probe')
    pub = node.create_publisher(String, 'probe_topic', 10)
    infos = []
    def burn():
        end = time.thread_time() + 0.01
        while time.thread_time() < end:
            pass
        pub.publish(String(data='x'))
    def hear(msg, info):
        infos.append(info)
    node.create_timer(0.05, burn)
    node.create_subscription(String, 'probe_topic', hear, 10)
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    path = callback_cpu.write(node.get_fully_qualified_name())
    print(installed, path, len(infos), type(infos[0]).__name__ if infos else None)
    node.destroy_node()
    rclpy.shutdown()
    """
)


def _probe(env: dict[str, str]) -> list[str]:
    done = subprocess.run(
        [sys.executable, '-c', PROBE],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return done.stdout.split()


@pytest.mark.node
def test_a_process_writes_its_callbacks_cpu_when_asked(tmp_path: Path) -> None:
    env = {**os.environ, callback_cpu.ENV: str(tmp_path / 'calls')}
    installed, path, heard, info = _probe(env)
    assert installed == 'True'
    assert path == str(tmp_path / 'calls' / 'probe.json')
    assert int(heard) >= 5
    assert info == 'dict', 'the subscription lost its message info'
    doc = json.loads(Path(path).read_text())
    assert doc['process'] == '/probe'
    assert doc['cpu_seconds'] > 0.0
    calls, spent = doc['callbacks']['timer probe burn']
    assert calls >= 10
    assert spent >= 0.01 * calls * 0.9, (calls, spent)
    heard_calls, _ = doc['callbacks']['sub probe probe_topic']
    assert heard_calls == int(heard)
    assert doc['publish']['/probe_topic'][0] == calls
    # The trace: every call, on the wall clock, with its CPU.
    trace = json.loads((tmp_path / 'calls' / 'probe.trace').read_text())
    assert trace['process'] == '/probe'
    burns = [c for c in trace['calls'] if c[3] == 'timer probe burn']
    assert len(burns) == calls
    assert all(b - a >= cpu * 0.99 and cpu >= 0.009 for a, b, cpu, _ in burns)
    assert sum(c[3] == 'pub /probe_topic' for c in trace['calls']) == calls
    ends = [c[1] for c in trace['calls']]
    assert ends == sorted(ends)  # in the order the calls ended

    collected = callback_cpu.collect(tmp_path / 'calls')
    assert list(collected) == ['/probe']
    first = callback_cpu.top(collected, 1)[0]
    assert first['callback'] == 'timer probe burn'
    assert first['ms_per_call'] >= 9.0


@pytest.mark.node
def test_without_the_variable_nothing_is_timed(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != callback_cpu.ENV}
    installed, path, heard, _ = _probe(env)
    assert installed == 'False'
    assert path == 'None'
    assert int(heard) >= 5


def test_collect_skips_what_it_cannot_read(tmp_path: Path) -> None:
    (tmp_path / 'bad.json').write_text('{not json')
    (tmp_path / 'other.json').write_text(json.dumps({'no': 'process'}))
    doc = {'process': '/a', 'cpu_seconds': 1.0, 'callbacks': {'t': [2, 0.5]}, 'publish': {}}
    (tmp_path / 'a.json').write_text(json.dumps(doc))
    collected = callback_cpu.collect(tmp_path)
    assert list(collected) == ['/a']
    assert callback_cpu.top(collected) == [
        {'process': '/a', 'callback': 't', 'calls': 2, 'cpu_s': 0.5, 'ms_per_call': 250.0}
    ]


def test_a_plain_yes_writes_beside_the_process(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(callback_cpu.ENV, '1')
    assert callback_cpu.enabled()
    assert callback_cpu.output_dir() == Path('callbacks')
    monkeypatch.setenv(callback_cpu.ENV, '/tmp/x')
    assert callback_cpu.output_dir() == Path('/tmp/x')
    monkeypatch.setenv(callback_cpu.ENV, '')
    assert not callback_cpu.enabled()
