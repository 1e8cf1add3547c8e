"""Every custom message type crosses a process boundary over DDS with its values intact."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

HELPER = Path(__file__).parent / 'helpers' / 'message_samples.py'
_spec = importlib.util.spec_from_file_location('message_samples', HELPER)
assert _spec is not None
assert _spec.loader is not None
samples = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(samples)

pytestmark = pytest.mark.graph


def test_all_custom_messages_import_in_a_fresh_process() -> None:
    names = ', '.join(samples.MESSAGE_TYPES)
    out = subprocess.run(
        [sys.executable, '-c', f'from activesurv_interfaces.msg import {names}; print("ok")'],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'ok'


def test_each_custom_message_crosses_processes(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    import activesurv_interfaces.msg as m

    qos = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    node = rclpy_context.create_node('sample_checker')
    received: dict[str, Any] = {}
    for name in samples.MESSAGE_TYPES:
        node.create_subscription(
            getattr(m, name),
            f'sample/{name}',
            lambda msg, n=name: received.__setitem__(n, msg),
            qos,
        )
    proc = subprocess.Popen(
        [sys.executable, str(HELPER)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    try:
        ok = spin_until([node], lambda: len(received) == len(samples.MESSAGE_TYPES), timeout=60.0)
        assert ok, f'received only {sorted(received)}; publisher alive: {proc.poll() is None}'
    finally:
        proc.terminate()
        proc.wait(10)
        node.destroy_node()
    for name in samples.MESSAGE_TYPES:
        assert received[name] == samples.sample(name), name
    assert received['MarkerObservation'].reason == 'no marker in the image'
    assert list(received['DispatchPlan'].assignments[0].desired_positions) == [0.15, -0.3]
