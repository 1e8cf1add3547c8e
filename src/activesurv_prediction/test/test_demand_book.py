"""Per-object demands of continuous surveillance (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_prediction.demands import DemandBook, crossing_time
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.predictor import TargetPredictor


def _moving(vx: float, x0: float = 0.1, t_end: float = 3.0) -> TargetPredictor:
    """A filter fed 10 Hz fixes of an object moving along x at ``vx`` from ``x0``."""
    p = TargetPredictor(measurement_std=0.0005)
    for t in np.arange(0.0, t_end + 1e-9, 0.1):
        p.update(float(t), np.array([x0 + vx * t, 0.1]))
    return p


def test_interval_demands_run_from_the_entry_with_indices_in_time_order() -> None:
    p = _moving(0.02)
    book = DemandBook(interval=1.0)
    assert book.upcoming(p, 3.0, 3) == []  # no object confirmed yet
    assert book.start(entered=0.0) == 1
    first = book.upcoming(p, 3.0, 3)
    assert [t for _, t in first] == pytest.approx([4.0, 5.0, 6.0])
    assert [j for j, _ in first] == sorted(j for j, _ in first)
    later = book.upcoming(p, 4.5, 3)
    assert later[0] == first[1]  # the same demand keeps its index
    book.end()
    assert book.upcoming(p, 4.5, 3) == []
    assert book.start(entered=10.0) == 2
    assert min(j for j, _ in book.upcoming(p, 10.5, 3)) > max(j for j, _ in later)


def test_a_phase_puts_the_interval_instants_off_the_entry_frames_grid() -> None:
    p = _moving(0.02)
    plain, shifted = DemandBook(interval=1.0), DemandBook(interval=1.0, phase=0.05)
    plain.start(entered=0.5)  # an overhead frame's stamp; frames every 0.1 s
    shifted.start(entered=0.5)
    on = [t for _, t in plain.upcoming(p, 3.0, 3)]
    off = [t for _, t in shifted.upcoming(p, 3.0, 3)]
    assert on == pytest.approx([3.5, 4.5, 5.5])  # on the frames' grid
    assert off == pytest.approx([3.55, 4.55, 5.55])  # half a frame period off it
    assert [t for _, t in shifted.upcoming(p, 3.56, 1)] == pytest.approx([4.55])


def test_only_points_in_the_demand_region_are_demanded() -> None:
    p = _moving(0.02)  # at x = 0.16 at t = 3 s, 0.02 m/s
    book = DemandBook(interval=1.0, region=[0.0, 0.215, 0.0, 0.2])  # made 10 mm inside
    book.start(0.0)
    ts = [t for _, t in book.upcoming(p, 3.0, 5)]
    assert ts == pytest.approx([4.0, 5.0])  # x = 0.18, 0.20; 0.22 is out


def test_a_demand_once_promised_does_not_come_and_go_at_the_region_edge() -> None:
    # The instant at t = 5 falls at x = 0.20: 15 mm inside a region ending at 0.215, so it is
    # promised (10 mm inside at least). A filter that then sees the object 6 mm further on
    # puts it at 0.206: still in the region, the promise stays, where a fresh look (which
    # wants 10 mm inside) would not make it.
    book = DemandBook(interval=1.0, region=[0.0, 0.215, 0.0, 0.2], freeze=0.5)
    book.start(0.0)
    assert [t for _, t in book.upcoming(_moving(0.02), 3.0, 5)] == pytest.approx([4.0, 5.0])
    ahead = _moving(0.02, x0=0.106)
    assert [t for _, t in book.upcoming(ahead, 3.0, 5)] == pytest.approx([4.0, 5.0])
    fresh = DemandBook(interval=1.0, region=[0.0, 0.215, 0.0, 0.2], freeze=0.5)
    fresh.start(0.0)
    assert [t for _, t in fresh.upcoming(ahead, 3.0, 5)] == pytest.approx([4.0])
    # Outside the region and not yet close: withdrawn ...
    far = _moving(0.02, x0=0.13)
    assert [t for _, t in book.upcoming(far, 3.0, 5)] == pytest.approx([4.0])
    # ... but within the freeze time of its instant, a promise is kept whatever comes.
    book.upcoming(_moving(0.02), 4.6, 5)  # promised again
    assert [t for _, t in book.upcoming(far, 4.6, 5)] == pytest.approx([5.0])


def test_crossing_lines_are_demands_that_freeze_before_their_instant() -> None:
    p = _moving(0.02)
    t_cross = crossing_time(p, 0.25, 3.0)
    assert t_cross == pytest.approx(7.5, abs=0.05)
    assert crossing_time(p, 0.05, 3.0) is None  # behind it
    book = DemandBook(lines_x=[0.25, 0.3], freeze=1.0)
    book.start(0.0)
    got = book.upcoming(p, 3.0, 5)
    assert [t for _, t in got] == pytest.approx([7.5, 10.0], abs=0.05)
    # Within the freeze time the instant stays, whatever the prediction says.
    book.upcoming(p, 6.6, 5)
    q = _moving(0.04, x0=0.1, t_end=3.0)
    assert book.upcoming(q, 6.6, 5)[0][1] == pytest.approx(7.5, abs=0.05)


def test_bad_books_are_refused() -> None:
    with pytest.raises(PredictionError):
        DemandBook()
    with pytest.raises(PredictionError):
        DemandBook(interval=1.0, region=[0.0, 1.0])
    for phase in (-0.01, 1.0, float('nan')):
        with pytest.raises(PredictionError, match='phase'):
            DemandBook(interval=1.0, phase=phase)
