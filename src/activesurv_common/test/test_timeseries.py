"""Time series, frame buffer and the simulated-clock estimate (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.timeseries import ClockEstimate, TimeSeries


def test_timeseries_interpolates_and_keeps_out_of_order_samples_sorted() -> None:
    ts = TimeSeries(2)
    for t, v in ((1.0, [0.0, 0.0]), (3.0, [2.0, 4.0]), (2.0, [1.5, 1.0])):
        assert ts.add(t, v)
    assert ts.latest_time == 3.0
    assert np.allclose(ts.at(2.5), [1.75, 2.5])
    assert ts.at(3.1) is None
    assert np.allclose(ts.at(3.1, hold=0.2), [2.0, 4.0])
    assert not ts.add(4.0, [np.nan, 0.0])


def test_timeseries_extrapolates_a_motion_but_not_a_jump() -> None:
    ts = TimeSeries(2)
    ts.add(1.0, [0.10, 0.06])
    ts.add(1.1, [0.102, 0.06])  # 20 mm/s along x
    assert np.allclose(ts.at(1.2, hold=0.2, extrapolate=True), [0.104, 0.06])
    assert np.allclose(ts.at(1.2, hold=0.2), [0.102, 0.06])  # held without extrapolate
    assert ts.at(1.4, hold=0.2, extrapolate=True) is None  # beyond the hold
    ts.add(1.2, [100.0, 100.0])  # parked: a jump, held rather than flung further
    assert np.allclose(ts.at(1.25, 0.2, True, max_rate=1.0), [100.0, 100.0])


def test_clock_estimate_extrapolates_at_the_ticks_rate() -> None:
    c = ClockEstimate()
    assert c.now(0.0) is None
    for k in range(11):  # 50 Hz ticks of a clock running at half speed
        c.tick(0.01 * k, 100.0 + 0.02 * k)
    assert c.rate == pytest.approx(0.5)
    # 8 ms of wall time after the tick at 0.100 s simulated: 4 ms of simulated time.
    assert c.now(100.2 + 0.008) == pytest.approx(0.104)


def test_clock_estimate_stops_at_max_ahead_and_never_runs_back() -> None:
    c = ClockEstimate(max_ahead=0.05)
    c.tick(1.0, 10.0)
    c.tick(2.0, 11.0)
    assert c.now(20.0) == pytest.approx(2.05)  # a paused clock does not run away
    c.tick(2.01, 20.5)
    assert c.now(20.5) == pytest.approx(2.05)  # not back to 2.01
    c.tick(0.0, 30.0)  # a new run: the clock starts over
    assert c.now(30.0) == 0.0


def test_clock_estimate_is_not_made_late_by_a_tick_heard_late() -> None:
    """Ticks at 20 Hz of a clock at 2x real time, some heard up to 9 ms late (a busy
    process): readings follow the ticks heard earliest, not the last one heard."""
    c = ClockEstimate()
    rng = np.random.default_rng(3)
    origin = 50.0
    for k in range(1, 120):
        late = 0.009 if k % 7 == 0 else float(rng.uniform(0.0, 0.0005))
        c.tick(0.1 * k, origin + 0.05 * k + late)
    assert c.rate == pytest.approx(2.0, rel=1e-3)
    # The last tick (k = 119, simulated 11.9 s) is heard 9 ms late; 1 ms after it was sent:
    assert c.now(origin + 0.05 * 119 + 0.001) == pytest.approx(11.902, abs=1e-3)
    c.tick(12.0, origin + 0.05 * 120 + 0.009)  # heard late: read 9 ms after it was sent
    assert c.now(origin + 0.05 * 120 + 0.009) == pytest.approx(12.018, abs=1e-3)


def test_clock_estimate_reads_its_owners_mapping_exactly() -> None:
    """With the owner's mapping (simulated = (wall - wall0) * rate) no fit is read: ticks
    heard late change nothing, and it reads before any tick; a new run forgets the old
    mapping, and so does a tick that cannot be the mapping's (an old mapping played back)."""
    c = ClockEstimate(max_ahead=0.25)
    c.set_origin(50.0, 2.0)
    assert c.now(50.85) == pytest.approx(1.7)  # no tick handled yet (a stalled start)
    c.tick(0.1, 50.06)  # heard late (behind the mapping: as ticks are)
    assert c.now(50.87) == pytest.approx(1.74)
    c.set_origin(float('nan'), 2.0)  # ignored
    d = ClockEstimate()
    d.set_origin(1000.0, 1.0)  # a bag's old mapping ...
    d.tick(5.0, 10.0)  # ... and a tick 985 s behind it: another clock
    d.tick(5.1, 10.1)
    assert d.now(10.15) == pytest.approx(5.15, abs=1e-6)
    c.tick(0.0, 70.0)  # a new run
    c.tick(0.05, 70.05)
    assert c.now(70.06) == pytest.approx(0.06, abs=1e-6)  # the fit again, not 40 s


def test_clock_estimate_fits_no_held_start() -> None:
    """Ticks of a clock held at 0 before its run starts do not lie on its line."""
    c = ClockEstimate()
    for k in range(5):
        c.tick(0.0, 10.0 + 0.05 * k)  # waiting for subscribers
    c.tick(0.0, 10.21)
    for k in range(1, 6):  # the run starts at wall 10.25
        c.tick(0.05 * k, 10.25 + 0.05 * k)
    assert c.now(10.25 + 0.25 + 0.01) == pytest.approx(0.26, abs=1e-6)
