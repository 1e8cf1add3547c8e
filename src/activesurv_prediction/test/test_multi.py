"""Several objects at once: tracks from the overhead fixes, identities, staggered demands."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_prediction.demands import TargetGeometry
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.multi import MultiTracker

RATE = 10.0
GEOMETRY = TargetGeometry.create((0.0, -0.03, -0.03), (0.0, -1.0, 0.0))


def crossing(t: float, y: float, start: float, leftward: bool, speed: float = 0.02) -> np.ndarray:
    x = 0.48 - speed * (t - start) if leftward else 0.02 + speed * (t - start)
    return np.array([x, y])


def run(
    tracker: MultiTracker, paths: list[tuple[float, float, float, bool]], end: float, seed: int = 0
) -> list[tuple[float, list[tuple[int, np.ndarray]]]]:
    """Fixes of objects (y, start, stop, leftward) with 0.3 mm noise; returns, per frame, the
    confirmed tracks (id, estimate) and the truth."""
    rng = np.random.default_rng(seed)
    out = []
    for step in range(int(end * RATE)):
        t = step / RATE
        truth = [
            (n, crossing(t, y, t0, left))
            for n, (y, t0, t1, left) in enumerate(paths)
            if t0 <= t <= t1
        ]
        fixes = [xy + rng.normal(0.0, 3e-4, 2) for _, xy in truth]
        rng.shuffle(fixes)  # the locator's order means nothing
        tracker.update(t, fixes)
        tracker.check_timeout(t)
        est = [(e.object_id, e.xy) for e in tracker.estimates(t) if e.object_id]
        out.append((t, [(n, xy) for n, xy in truth], est))
    return out


def identities(frames: list) -> dict[int, set[int]]:
    """For each true object, the track ids that followed it (nearest within 15 mm)."""
    seen: dict[int, set[int]] = {}
    for _, truth, est in frames:
        for n, xy in truth:
            near = [(np.hypot(*(xy - e)), i) for i, e in est]
            if near and min(near)[0] < 0.015:
                seen.setdefault(n, set()).add(min(near)[1])
    return seen


def test_two_objects_passing_30_mm_apart_in_opposite_directions_keep_their_ids() -> None:
    tracker = MultiTracker(interval=2.0, at_once=2)
    paths = [(0.07, 0.5, 20.0, False), (0.10, 0.5, 20.0, True)]  # cross at t = 12 s, 30 mm
    frames = run(tracker, paths, 20.0)
    ids = identities(frames)
    assert set(ids) == {0, 1}
    assert all(len(v) == 1 for v in ids.values()), f'identity switch: {ids}'
    assert ids[0] != ids[1]
    # Both confirmed within about a second of entering; estimates within a millimetre.
    for t, truth, est in frames:
        if t > 2.0:
            assert len(est) == 2
            for _, xy in truth:
                assert min(np.hypot(*(xy - e)) for _, e in est) < 1e-3


def test_tracks_are_born_confirmed_and_die_and_ids_are_never_reused() -> None:
    tracker = MultiTracker(interval=2.0, at_once=2, lost_timeout=0.5)
    paths = [(0.06, 0.5, 6.0, False), (0.14, 3.0, 12.0, True), (0.06, 9.0, 14.0, False)]
    frames = run(tracker, paths, 15.0)
    assert tracker.objects == 3
    ids = identities(frames)
    assert [len(ids[n]) for n in range(3)] == [1, 1, 1]
    assert len(set().union(*ids.values())) == 3
    tracker.update(16.0, [])
    tracker.check_timeout(16.0)
    assert tracker.tracks == []


def test_a_stream_that_lags_the_clock_loses_no_track() -> None:
    """Fixes that arrive 0.9 s late, with a 0.45 s gap (a loaded start-up, measured in a
    session): the clock runs more than lost_timeout past the last fix, the stream does not."""
    tracker = MultiTracker(interval=2.0, at_once=2, lost_timeout=1.0)
    lag, t = 0.9, 0.5
    while t < 8.0:
        if not 3.0 < t < 3.45:  # frames lost on the way
            tracker.update(t, [crossing(t, 0.07, 0.5, False)])
        tracker.check_timeout(t + lag)  # the clock is ahead of the frames
        t = round(t + 0.1, 6)
    assert tracker.objects == 1  # one object, one identity
    assert [k.object_id for k in tracker.tracks] == [1]
    # A stream that stops for good: the clock ends the track after stream_grace as well.
    tracker.check_timeout(t + tracker.lost_timeout + tracker.stream_grace + 0.1)
    assert tracker.tracks == []


def test_demands_of_objects_at_once_are_staggered_and_indexed_across_objects() -> None:
    interval = 2.0
    tracker = MultiTracker(interval=interval, at_once=2)
    run(tracker, [(0.06, 0.5, 30.0, False), (0.14, 0.5, 30.0, True)], 8.0)
    demands = tracker.horizon(8.0, 4, GEOMETRY, 0.08)
    by_object: dict[int, list[float]] = {}
    for d in demands:
        by_object.setdefault(d.object_id, []).append(d.instant)
    assert len(by_object) == 2
    instants = sorted(d.instant for d in demands)
    assert min(np.diff(instants)) >= interval / 2 - 1e-6  # interval / N apart
    assert len({d.index for d in demands}) == len(demands)
    # Indices stay with their demands from one horizon to the next.
    again = {
        (d.object_id, round(d.instant, 6)): d.index
        for d in tracker.horizon(8.05, 4, GEOMETRY, 0.08)
    }
    for d in demands:
        key = (d.object_id, round(d.instant, 6))
        if key in again:
            assert again[key] == d.index


def test_objects_demands_keep_the_phase_off_the_frames_grid() -> None:
    tracker = MultiTracker(interval=2.0, at_once=2, phase=0.05)
    run(tracker, [(0.06, 0.5, 30.0, False), (0.14, 0.5, 30.0, True)], 8.0)
    demands = tracker.horizon(8.0, 4, GEOMETRY, 0.08)
    assert len({d.object_id for d in demands}) == 2
    for d in demands:  # entries are fix stamps (every 0.1 s): the instants sit between them
        assert (d.instant * 10.0) % 1.0 == pytest.approx(0.5, abs=1e-6)


def test_bad_fixes_are_refused() -> None:
    tracker = MultiTracker()
    with pytest.raises(PredictionError):
        tracker.update(0.0, [[np.nan, 0.1]])
    with pytest.raises(PredictionError):
        MultiTracker(at_once=0)


@pytest.mark.parametrize('n', [1, 3, 10])
def test_n_objects_side_by_side_get_n_tracks(n: int) -> None:
    """Ten objects 15 mm apart in both directions: one confirmed track each (make bench
    measures the time per frame)."""
    tracker = MultiTracker(interval=2.0, at_once=n)
    ys = np.linspace(0.03, 0.17, n)
    run(tracker, [(y, 0.0, 10.0, bool(i % 2)) for i, y in enumerate(ys)], 3.0)
    assert len([k for k in tracker.tracks if k.confirmed]) == n
    assert tracker.objects == n


def test_a_frame_older_than_a_track_update_is_taken_without_error() -> None:
    # Overhead frames can arrive out of order (two fixes of one stamp, a late frame): a fix
    # older than a track's last update must neither raise nor start a duplicate track.
    tracker = MultiTracker(interval=2.0, at_once=2)
    for step in range(20):
        t = step / RATE
        tracker.update(t, [crossing(t, 0.07, 0.0, False)])
    before = len(tracker.tracks)
    late = 1.9 - 0.05
    tracker.update(late, [crossing(late, 0.07, 0.0, False), np.array([0.3, 0.15])])
    assert len(tracker.tracks) == before
    tracker.update(2.0, [crossing(2.0, 0.07, 0.0, False), np.array([0.3, 0.15])])
    assert len(tracker.tracks) == before + 1


@pytest.mark.parametrize('model', ['imm', 'ca'])
def test_the_fix_path_imports_nothing(model: str) -> None:
    """A tracker pays its imports when it is made (at the node's start), never on a fix: the
    first association imported scipy.optimize on a fix, which stalled the predictor and the
    dispatcher 3.5 s on a loaded 2-core host and lost the first demands of two objects."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent(f"""
        import sys
        import numpy as np
        from activesurv_prediction.multi import MultiTracker
        tracker = MultiTracker(model={model!r}, interval=2.0, at_once=2)
        before = set(sys.modules)
        for step in range(60):
            t = step / 10.0
            fixes = [np.array([0.02 + 0.02 * t, 0.06])]
            if t > 1.0:
                fixes.append(np.array([0.48 - 0.02 * t, 0.14]))
            tracker.update(t, fixes)
            tracker.check_timeout(t)
        assert [e.object_id for e in tracker.estimates(6.0)] == [1, 2], tracker.estimates(6.0)
        print(sorted({{m.split('.')[0] for m in set(sys.modules) - before}}))
    """)
    r = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == '[]', f'imported on a fix: {r.stdout}'
