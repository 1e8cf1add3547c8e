"""A session's truth per demand: the table's states around the instant, never its last state
held past them (a stop can end the table before the last demand's instant)."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.timeseries import TimeSeries
from activesurv_evaluation.session import _nearest, _objects_at


def _lane(times: list[float], x0: float, speed: float) -> tuple[TimeSeries, TimeSeries]:
    truth, present = TimeSeries(6), TimeSeries(1)
    for t in times:
        truth.add(t, np.array([x0 + speed * t, 0.1, 0.05, 0.0, -1.0, 0.0]))
        present.add(t, np.array([1.0]))
    return truth, present


def test_an_instant_between_states_gets_them_interpolated() -> None:
    truth, present = _lane([30.0, 30.1, 30.2], 0.0, 0.02)
    (s,) = _objects_at({0: truth}, {0: present}, 30.15)
    assert s[0] == pytest.approx(0.02 * 30.15)


def test_an_instant_past_the_last_state_has_no_truth_not_a_stale_one() -> None:
    # The table's last state 0.25 s before the instant: held, it would be 5 mm off.
    truth, present = _lane([31.65, 31.75, 31.85], 0.0, 0.02)
    (s,) = _objects_at({0: truth}, {0: present}, 32.1)
    assert np.all(np.isnan(s))
    # Within the stamps' rounding of the last state, that state.
    (s,) = _objects_at({0: truth}, {0: present}, 31.8505)
    assert s[0] == pytest.approx(0.02 * 31.85)


def test_an_object_gone_from_the_table_is_not_there() -> None:
    truth, present = _lane([1.0, 1.1], 0.0, 0.02)
    present.add(1.2, np.array([0.0]))
    assert _objects_at({0: truth}, {0: present}, 1.25) == []


def test_the_nearest_object_is_a_known_one_when_there_is_one() -> None:
    unknown = np.full(6, np.nan)
    known = np.array([0.5, 0.1, 0.05, 0.0, -1.0, 0.0])
    assert _nearest([unknown, known], np.array([0.0, 0.0, 0.0])) is known
    assert _nearest([unknown], np.array([0.0, 0.0, 0.0])) is unknown
