"""A demand's latency budget from the receive times of its messages (no ROS)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from activesurv_evaluation.timing import (
    StepTimes,
    budget,
    camera_delays,
    compute_on_cores,
    compute_unsplit,
    critical_compute,
    empty_timing,
    frames_bound,
    largest_wait,
    plot_budget,
)


def _stamped(t: float) -> SimpleNamespace:
    sec = int(t)
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=round((t - sec) * 1e9)))
    )


def _obs(
    cam: str, offset: float = 0.0, status: int = 0, compute: float = 0.004
) -> SimpleNamespace:
    return SimpleNamespace(camera_id=cam, frame_offset=offset, status=status, compute_time=compute)


def test_each_step_after_the_instant() -> None:
    steps = StepTimes()
    t = 10.0
    # cam1: a promised state before the instant; cam2: its state 3 ms after it
    assert steps.hear('/cam1/stage/joint_states', _stamped(9.95), 9.951)
    assert steps.hear('/cam1/stage/joint_states', _stamped(t), 9.8)
    assert steps.hear('/cam2/stage/joint_states', _stamped(t), 10.003)
    assert steps.hear('/cam1/image_raw', _stamped(t), 10.005)
    assert steps.hear('/cam2/image_raw', _stamped(t + 0.010), 10.018)  # free-running: +10 ms
    assert not steps.hear('/marker_observations', _stamped(t), 10.02)
    observed = [(_obs('cam1'), 10.011), (_obs('cam2', 0.010, compute=0.006), 10.025)]
    timing = steps.timing(t, ['cam1', 'cam2'], observed, 10.027)
    assert abs(timing['stage_state'] - 0.003) < 1e-9
    assert abs(timing['frames']['cam1'] - 0.005) < 1e-9
    assert abs(timing['frames']['cam2'] - 0.018) < 1e-9
    assert abs(timing['observations']['cam2'] - 0.025) < 1e-9
    assert abs(timing['estimate'] - 0.027) < 1e-9
    assert critical_compute(timing) == 0.006
    names = [n for n, _ in budget(timing)]
    assert names == ['stage state', 'frames', 'observations', 'fusion']
    assert abs(sum(s for _, s in budget(timing)) - 0.027) < 1e-9
    assert largest_wait([timing])[0] == 'frames'  # 3 -> 18 ms


def test_the_critical_path_holds_fusions_compute_and_the_cores_shared() -> None:
    """Fusion's processing is on every demand's critical path; with k imagings on fewer cores,
    the least time is their sum over the cores where that exceeds the slowest one."""
    steps = StepTimes()
    observed = [(_obs(c, compute=0.004), 1.01) for c in ('cam1', 'cam2', 'cam3')]
    timing = steps.timing(1.0, ['cam1', 'cam2', 'cam3'], observed, 1.02, 0.015, 0.001)
    assert timing['fusion_compute'] == 0.001
    assert abs(critical_compute(timing) - 0.005) < 1e-12  # type: ignore[operator]
    assert abs(compute_on_cores(timing, 2) - 0.007) < 1e-12  # type: ignore[operator]
    assert abs(compute_on_cores(timing, 4) - 0.005) < 1e-12  # type: ignore[operator]
    older = steps.timing(1.0, ['cam1'], observed[:1], 1.02)  # a bag from before: no fusion's
    assert older['fusion_compute'] is None
    assert critical_compute(older) == 0.004
    assert compute_on_cores(empty_timing(), 2) is None


def test_each_imaging_on_one_core_the_busiest_core_bounds_the_demand() -> None:
    """Three 4 ms imagings on two cores take 8 ms when each stays on one core (6 ms were the
    work divisible); the best assignment, not the order heard, decides it."""
    timing = {'compute': {'cam1': 0.004, 'cam2': 0.004, 'cam3': 0.004}, 'fusion_compute': 0.001}
    assert abs(compute_unsplit(timing, 2) - 0.009) < 1e-12  # type: ignore[operator]
    assert abs(compute_on_cores(timing, 2) - 0.007) < 1e-12  # type: ignore[operator]
    assert abs(compute_unsplit(timing, 3) - 0.005) < 1e-12  # type: ignore[operator]
    uneven = {'compute': {'a': 0.002, 'b': 0.005, 'c': 0.003, 'd': 0.004}, 'fusion_compute': None}
    assert abs(compute_unsplit(uneven, 2) - 0.007) < 1e-12  # type: ignore[operator]  # 5+2, 4+3
    many = {'compute': {f'c{i}': 0.001 for i in range(14)}}  # past brute force: longest first
    assert abs(compute_unsplit(many, 4) - 0.004) < 1e-12  # type: ignore[operator]
    wide = {'compute': {f'c{i}': 0.001 * (i % 3 + 1) for i in range(12)}}  # 8 cores: at once
    assert abs(compute_unsplit(wide, 8) - 0.003) < 1e-12  # type: ignore[operator]
    assert compute_unsplit(empty_timing(), 2) is None
    assert compute_unsplit(timing, 0) is None


def test_missing_steps_are_null() -> None:
    steps = StepTimes()
    timing = steps.timing(5.0, ['cam3'], [(_obs('cam3', status=3), 5.2)], None)
    assert timing['stage_state'] is None
    assert timing['frames'] == {}
    assert timing['estimate'] is None
    assert empty_timing(0.02)['estimate'] == 0.02
    assert critical_compute(empty_timing()) is None
    assert largest_wait([]) is None


def test_the_budget_is_drawn(tmp_path: Path) -> None:
    rows = [
        {'index': j, 'timing': {'stage_state': 0.001, 'frames': {'cam1': 0.004},
                                'observations': {'cam1': 0.01}, 'estimate': 0.012}}
        for j in range(3)
    ]  # fmt: skip
    png = plot_budget(rows, tmp_path / 'latency.png', 'budget')
    assert png is not None
    assert png.stat().st_size > 1000
    assert plot_budget([{'index': 0, 'timing': empty_timing()}], tmp_path / 'no.png', 'x') is None
    three = {c: 0.004 for c in ('cam1', 'cam2', 'cam3')}
    rows = [{'index': 0, 'timing': {**rows[0]['timing'], 'compute': three}}]
    assert plot_budget(rows, tmp_path / 'cores.png', 'budget', cores=2) is not None


def test_without_frames_in_the_bag_the_imager_says_when_its_frame_came() -> None:
    """A hardware run records only the frames used, after imaging: the frame step is the
    observation's own ``frame_received`` (the imager's clock); NaN (older imagers) is none."""
    steps = StepTimes()
    told = SimpleNamespace(**vars(_obs('cam1', 0.012)), frame_received=0.041)
    unknown = SimpleNamespace(**vars(_obs('cam2')), frame_received=float('nan'))
    timing = steps.timing(3.0, ['cam1', 'cam2'], [(told, 3.05), (unknown, 3.06)], 3.07)
    assert timing['frames'] == {'cam1': 0.041}
    assert largest_wait([timing]) is not None


def test_the_producers_own_times_come_before_what_the_recorder_heard() -> None:
    """Observations and the estimate say when they were published (their producers' clocks):
    the budget takes those; the recorder's (later) hearing stays under ``heard``."""
    steps = StepTimes()
    t = 4.0
    o = _obs('cam1')
    o.frame_received, o.published = 0.001, 0.0045
    timing = steps.timing(t, ['cam1'], [(o, 4.012)], 4.015, 0.005)
    assert abs(timing['frames']['cam1'] - 0.001) < 1e-9
    assert abs(timing['observations']['cam1'] - 0.0045) < 1e-9
    assert abs(timing['estimate'] - 0.005) < 1e-9
    assert abs(timing['heard']['observations']['cam1'] - 0.012) < 1e-9
    assert abs(timing['heard']['estimate'] - 0.015) < 1e-9


def test_a_cameras_own_delay_is_its_frames_arrival_after_exposure() -> None:
    demands = [
        {'frame_offsets': {'cam1': 0.010, 'cam2': -0.02}, 'timing': {'frames': {'cam1': 0.09}}},
        {'frame_offsets': {'cam3': 0.0}, 'timing': {'frames': {'cam3': 0.05, 'cam4': 0.06}}},
        {'frame_offsets': {}, 'timing': {}},
    ]
    assert [round(x, 9) for x in camera_delays(demands)] == [0.08, 0.05]


def test_a_demands_own_bound_is_its_slowest_frame_plus_its_compute() -> None:
    timing = {
        'frames': {'cam1': 0.090, 'cam2': 0.125, 'cam3': None},
        'compute': {'cam1': 0.003, 'cam2': 0.004},
        'fusion_compute': 0.001,
    }
    assert round(frames_bound({'timing': timing}) or 0.0, 9) == 0.130
    assert frames_bound({'timing': {**timing, 'compute': {}}}) is None
    assert frames_bound({'timing': {**timing, 'frames': {}}}) is None
    assert frames_bound({}) is None
