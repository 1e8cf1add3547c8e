"""The stage state at a demand instant, promised while the axes stand still (pure core)."""

from __future__ import annotations

from activesurv_stages.promises import Promises


def test_a_standing_bridge_promises_at_once_and_the_report_keeps_it() -> None:
    p = Promises()
    p.request(10.0, now=9.7)
    p.request(9.0, now=9.7)  # past: nothing to promise
    assert p.due(9.7, standing_still=False, positions={'x': 0.1}) == []  # still arriving
    assert p.due(9.8, standing_still=True, positions={'x': 0.1}) == [(10.0, {'x': 0.1})]
    assert p.due(9.81, standing_still=True, positions={'x': 0.1}) == []  # promised once
    assert p.check(9.9, {'x': 0.1}) == []  # before the instant: nothing to check
    assert p.check(10.02, {'x': 0.10002}) == []
    assert (p.kept, p.broken) == (1, 0)


def test_a_broken_promise_is_said_and_counted() -> None:
    p = Promises()
    p.request(5.0, now=4.7)
    p.due(4.8, True, {'x': 0.1, 'yaw': 0.2})
    (why,) = p.check(5.01, {'x': 0.1, 'yaw': 0.25})
    assert 'yaw by +0.05' in why
    assert (p.kept, p.broken) == (0, 1)


def test_an_instant_passed_before_the_axes_stopped_is_never_promised() -> None:
    p = Promises()
    p.request(5.0, now=4.7)
    assert p.due(5.1, True, {'x': 0.1}) == []
    assert p.pending == set()


def test_a_hold_promises_the_state_past_the_instant_and_checks_it_there() -> None:
    # Free-running cameras: the frame nearest the instant may come after it; the dispatcher
    # holds the cameras still until instant + hold, and the bridge says so.
    p = Promises(hold=0.022)
    p.request(10.0, now=9.7)
    assert p.due(9.8, True, {'x': 0.1}) == [(10.0, {'x': 0.1}), (10.022, {'x': 0.1})]
    assert p.check(10.01, {'x': 0.1}) == []  # the instant's promise kept
    assert (p.kept, p.broken) == (1, 0)
    (why,) = p.check(10.03, {'x': 0.2})  # moved before the hold ended
    assert '10.022' in why
    assert (p.kept, p.broken) == (1, 1)
