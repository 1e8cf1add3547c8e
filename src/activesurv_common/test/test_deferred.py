"""Work deferred past a demand instant's critical path (``activesurv_common.ros.deferred``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest

from activesurv_common.ros.deferred import Deferred


def _spin(executor: Any, predicate: Callable[[], bool], timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not predicate():
        executor.spin_once(timeout_sec=0.01)
    return predicate()


@pytest.fixture(params=['events', 'single'])
def executor(request: Any, rclpy_context: Any, monkeypatch: pytest.MonkeyPatch) -> Any:
    """Both executors our processes spin: the graph's EventsExecutor takes the timers a
    callback makes while it spins."""
    from activesurv_common.ros.node import make_executor

    monkeypatch.setenv('ACTIVESURV_EXECUTOR', request.param)
    ex = make_executor()
    yield ex
    ex.shutdown()


def test_deferred_work_runs_after_its_delay_in_order(rclpy_context: Any, executor: Any) -> None:
    node = rclpy_context.create_node('deferred_order')
    executor.add_node(node)
    later = Deferred(node, 0.05)
    done: list[tuple[str, float]] = []
    try:
        start = time.monotonic()

        def note(name: str) -> Callable[[], None]:
            return lambda: done.append((name, time.monotonic() - start))

        def from_a_callback() -> None:  # as a camera's call at an instant defers its views
            timer.cancel()
            later(note('a'))
            later(note('b'))

        timer = node.create_timer(0.001, from_a_callback)
        assert _spin(executor, lambda: len(later) == 2)
        assert done == []  # nothing before the delay
        time.sleep(0.01)
        later(note('c'))  # handed over later: waits its own delay
        assert _spin(executor, lambda: len(done) == 3)
        assert [n for n, _ in done] == ['a', 'b', 'c']
        assert all(t >= 0.05 for _, t in done)
        assert done[2][1] >= 0.06  # c's own delay, not a's
        assert later.ran == 3
        assert len(later) == 0
    finally:
        node.destroy_node()


def test_flush_runs_what_waits_at_once_and_the_timer_then_does_nothing(
    rclpy_context: Any, executor: Any
) -> None:
    node = rclpy_context.create_node('deferred_flush')
    executor.add_node(node)
    later = Deferred(node, 0.02)
    done: list[int] = []
    try:
        later(lambda: done.append(1))
        later(lambda: done.append(2))
        later.flush()  # a node's stop
        assert done == [1, 2]
        assert len(later) == 0
        end = time.monotonic() + 0.1
        _spin(executor, lambda: time.monotonic() > end)
        assert done == [1, 2]  # each once
    finally:
        node.destroy_node()


def test_a_zero_delay_runs_at_once_and_a_bad_delay_is_refused(rclpy_context: Any) -> None:
    node = rclpy_context.create_node('deferred_zero')
    try:
        done: list[int] = []
        Deferred(node, 0.0)(lambda: done.append(1))
        assert done == [1]
        for bad in (-0.01, float('nan'), float('inf')):
            with pytest.raises(ValueError, match='delay'):
                Deferred(node, bad)
    finally:
        node.destroy_node()


def test_a_flush_logs_work_that_fails_and_runs_the_rest(rclpy_context: Any) -> None:
    """At a stop the context may be going: one publish that raises does not cost the rest."""
    node = rclpy_context.create_node('deferred_failing')
    try:
        later = Deferred(node, 1.0)
        done: list[int] = []

        def broken() -> None:
            raise RuntimeError('context is not valid')

        later(lambda: done.append(1))
        later(broken)
        later(lambda: done.append(3))
        later.flush()
        assert done == [1, 3]
        assert later.failed == 1
        assert len(later) == 0
    finally:
        node.destroy_node()
