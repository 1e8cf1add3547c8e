"""The table's states a camera imaging on requests needs: those around its instants."""

from __future__ import annotations

import math

import pytest

from activesurv_sim.instant_window import InstantWindows


def test_only_the_states_in_an_instants_window_are_sent_each_once() -> None:
    w: InstantWindows[str] = InstantWindows(before=0.2, after=0.1)
    w.requested(1.0)
    w.requested(1.1)  # overlapping windows: a state is still sent once
    sent = [
        s
        for t in (0.7, 0.75, 0.85, 0.95, 1.0, 1.05, 1.15, 1.21, 1.3)
        for s in w.published(t, [f'{t}'])
    ]
    assert sent == ['0.85', '0.95', '1.0', '1.05', '1.15']
    assert w.published(1.0, ['again']) == ()  # the same stamp again: sent already


def test_a_late_request_gets_the_states_of_its_window_published_already() -> None:
    w: InstantWindows[str] = InstantWindows(before=0.2, after=0.1)
    for t in (0.5, 0.85, 0.95):
        assert w.published(t, [f'a{t}', f'b{t}']) == ()  # no instant asked for yet
    assert w.requested(1.0) == ['a0.85', 'b0.85', 'a0.95', 'b0.95']
    assert w.requested(1.0) == []  # asked again: nothing new
    assert list(w.published(1.0, ['x'])) == ['x']
    assert w.requested(0.5) == ['a0.5', 'b0.5']  # after its instant (kept for a while)


def test_old_states_and_instants_are_forgotten() -> None:
    w: InstantWindows[int] = InstantWindows(before=0.1, after=0.1, keep=1.0)
    w.requested(0.0)
    for i in range(1, 400):
        w.published(i * 0.05, [i])
    assert w.requested(0.5) == []  # beyond ``keep``: gone
    assert len(w._history) <= 21
    assert len(w._sent) <= 21
    assert w._instants == [0.5]


@pytest.mark.parametrize('bad', [-0.1, math.nan, math.inf])
def test_a_bad_window_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match='before'):
        InstantWindows(before=bad, after=0.1)


def test_a_non_finite_stamp_is_ignored() -> None:
    w: InstantWindows[int] = InstantWindows(before=0.1, after=0.1)
    w.requested(math.nan)
    assert w.published(math.nan, [1]) == ()


def test_a_camera_hears_every_state_unless_it_images_on_requests_only() -> None:
    from activesurv_common.ros import topics
    from activesurv_sim.conversions import object_topic
    from activesurv_sim.errors import SimError

    assert object_topic({}) == topics.OBJECT_STATE
    assert object_topic({'instant_states': True}) == topics.INSTANT_OBJECT_STATE
    for stream in ({'frame_rate': 15.0}, {'preview_rate': 2.0}):
        with pytest.raises(SimError, match='imaging on requests only'):
            object_topic({'instant_states': True, **stream})
