"""The pacer lets a rate through on average, whatever the jitter of the events."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.errors import CommonError
from activesurv_common.pacing import Backoff, ExposureClock, Pacer, PhaseLock, ViewThrottle


def test_a_faster_stream_is_thinned_to_the_rate() -> None:
    p = Pacer(10.0, burst=1.0)
    kept = [p.ready(k / 30.0) for k in range(90)]  # 30 Hz for 3 s
    assert sum(kept) == 30
    assert kept[:4] == [True, False, False, True]


def test_late_events_are_made_up_for_so_the_mean_rate_holds() -> None:
    # States at 20 Hz with 40 ms of jitter and one in ten 100 ms late: a 10 Hz periodic
    # timer that loses late ticks falls short; the pacer keeps 10 Hz on average.
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 20.0, 0.05) + rng.uniform(0.0, 0.04, 400)
    t[::10] += 0.1
    p = Pacer(10.0)
    passed = [x for x in np.sort(t) if p.ready(float(x))]
    assert 198 <= len(passed) <= 201
    # A 1 s stall is not paid back with a burst of ten: at most ``burst`` in a row.
    p = Pacer(10.0, burst=2.0)
    assert p.ready(0.0)
    assert [p.ready(1.0) for _ in range(4)] == [True, True, False, False]


def test_bad_rates_are_refused() -> None:
    with pytest.raises(CommonError, match='rate'):
        Pacer(0.0)
    with pytest.raises(CommonError, match='burst'):
        Pacer(10.0, burst=0.5)


@pytest.mark.parametrize('first', [0.0, 0.0008, 0.0499])
def test_phase_lock_takes_the_same_stamps_whatever_the_first(first: float) -> None:
    """20 Hz states with jitter, a 10 Hz stream on the grid 0.05 + n / 10: the states stamped
    near 0.05, 0.15, ... pass, wherever the stream started; a missing one is made up for."""
    lock = PhaseLock(10.0, 0.05)
    rng = np.random.default_rng(1)
    stamps = [first] + [0.05 * k + float(rng.uniform(-0.002, 0.002)) for k in range(1, 40)]
    taken = [t for t in stamps if lock.ready(t)]
    grid = [round(t * 20) for t in taken if t > 0.04]
    assert grid == list(range(1, 40, 2))  # 0.05, 0.15, ... (in 50 ms steps: odd)
    lock = PhaseLock(10.0, 0.05)
    gap = [t for t in (0.05, 0.1, 0.2, 0.25, 0.3, 0.35) if lock.ready(t)]
    assert gap == [0.05, 0.2, 0.25, 0.35]  # 0.15 missing: 0.2 stands in for it


def test_view_throttle_thins_moves_and_lets_changes_through_at_once() -> None:
    throttle = ViewThrottle(0.2)
    stamps = np.round(np.arange(0.0, 2.0, 0.1), 3)
    passed = [float(t) for t in stamps if throttle.due(float(t), 'same roles')]
    assert passed == pytest.approx(np.arange(0.0, 2.0, 0.2))  # one per period, on the grid
    assert not throttle.due(1.95, 'same roles')
    assert throttle.due(1.96, 'new roles')  # a change in kind goes at once
    assert not throttle.due(1.97, 'new roles')
    assert throttle.due(1.0, 'new roles')  # the clock went back (a replay restarted): send


def test_view_throttle_period_zero_lets_all_through_and_bad_periods_are_refused() -> None:
    every = ViewThrottle(0.0)
    assert all(every.due(0.01 * i, 'k') for i in range(10))
    for bad in (-0.1, float('nan'), float('inf')):
        with pytest.raises(CommonError, match='period'):
            ViewThrottle(bad)


def test_an_exposure_clock_returns_every_exposure_on_its_grid_however_late_it_is_asked() -> None:
    clock = ExposureClock(30.0, 100.0)
    assert clock.due(99.99) == []
    assert clock.due(100.0) == [100.0]
    assert clock.due(100.01) == []
    late = clock.due(100.2)  # asked 170 ms late: the five exposures since, on the grid
    assert late == pytest.approx([100.0 + n / 30.0 for n in range(1, 7)])
    assert clock.due(100.2) == []
    assert clock.lost == 0
    stalled = clock.due(103.0)  # a 2.8 s stall: the last second's exposures, the rest lost
    assert len(stalled) == 31
    assert stalled[0] == pytest.approx(102.0)
    assert stalled[-1] == pytest.approx(103.0)
    assert clock.lost == 53  # exposures 7-59: older than a second when asked
    with pytest.raises(CommonError):
        ExposureClock(0.0, 0.0)


def test_a_backoff_doubles_while_polls_find_nothing_and_starts_over_when_one_does() -> None:
    b = Backoff(0.5, 4.0)
    assert [b.after(False) for _ in range(5)] == [1.0, 2.0, 4.0, 4.0, 4.0]
    assert b.after(True) == 0.5
    assert b.after(False) == 1.0
    assert Backoff(0.5, 0.5).after(False) == 0.5  # maximum == base: a fixed period
    with pytest.raises(CommonError):
        Backoff(0.5, 0.25)
