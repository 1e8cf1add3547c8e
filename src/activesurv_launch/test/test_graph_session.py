"""GraphSession: start, wait until the nodes are up, stop on every way out (no ROS)."""

from __future__ import annotations

import os
import signal
from collections.abc import Sequence
from typing import Any

import pytest

from activesurv_common.lifetime import StopRequested
from activesurv_launch.errors import NodeDiedError
from activesurv_launch.launcher import NodeSpec
from activesurv_launch.session import GraphSession


class FakeRunner:
    def __init__(self) -> None:
        self.started: list[str] = []
        self.stopped = 0
        self.dead = False

    def run(self, specs: Sequence[NodeSpec]) -> None:
        self.started += [s.name for s in specs]

    def check(self) -> None:
        if self.dead:
            raise NodeDiedError('node /x died')

    def stop(self) -> Any:
        self.stopped += 1

    def cpu_seconds(self) -> dict[str, float]:
        return {}

    def rss_bytes(self) -> dict[str, int]:
        return {}


SPECS = [NodeSpec('a', 'm'), NodeSpec('b', 'm')]


def test_it_waits_for_the_nodes_and_stops_them_on_exit() -> None:
    runner = FakeRunner()
    up: list[str] = []

    def spin(_: float) -> None:
        up.append(f'n{len(up)}')

    with GraphSession(
        runner, SPECS, lambda: {'a', 'b'} - {'a', 'b'} if len(up) > 2 else {'a'}, spin
    ):
        assert runner.started == ['a', 'b']
        assert len(up) >= 3
        assert runner.stopped == 0
    assert runner.stopped == 1


def test_an_error_inside_still_stops_the_nodes() -> None:
    runner = FakeRunner()
    with (
        pytest.raises(ValueError, match='boom'),
        GraphSession(runner, SPECS, lambda: set(), lambda _: None),
    ):
        raise ValueError('boom')
    assert runner.stopped == 1


def test_nodes_that_never_come_up_or_die_are_reported_and_stopped() -> None:
    runner = FakeRunner()
    session = GraphSession(runner, SPECS, lambda: {'b'}, lambda _: None, startup_timeout=0.0)
    with pytest.raises(NodeDiedError, match=r"did not come up in 0 s: \['b'\]"):
        session.__enter__()
    assert runner.stopped == 1
    runner = FakeRunner()
    runner.dead = True
    session = GraphSession(runner, SPECS, lambda: {'b'}, lambda _: None)
    with pytest.raises(NodeDiedError, match='died'):
        session.__enter__()
    assert runner.stopped == 1


@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_asks_for_a_clean_stop_then_raises_after_the_nodes_stopped(sig: int) -> None:
    runner = FakeRunner()
    old = signal.getsignal(sig)
    graph = GraphSession(runner, SPECS, lambda: set(), lambda _: None)
    graph.__enter__()
    os.kill(os.getpid(), sig)
    assert graph.stopping == signal.Signals(sig).name  # the block finishes its work
    assert runner.stopped == 0
    with pytest.raises(StopRequested) as info:
        graph.__exit__(None, None, None)
    assert runner.stopped == 1
    assert info.value.exit_status == 128 + sig
    assert signal.getsignal(sig) == old  # the handlers are given back
