"""The simulator's clock over DDS: the xy table owns /clock, a simulated stage stamps its joint
states with it, and the object moves along its path from its start time (two node processes)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from activesurv_common.ros import qos, topics


@pytest.mark.graph
def test_xy_table_and_sim_stage_on_simulated_time(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    from activesurv_interfaces.msg import ObjectState
    from activesurv_launch.launcher import Launcher, NodeSpec

    specs = [
        NodeSpec(
            'xy_table',
            'activesurv_sim.xy_table_node',
            # Simulated time starts when this test's peer listens (discovery may be slow).
            parameters={'real_time_factor': 2.0, 'start_time': 0.5, 'wait_for_subscribers': 1},
        ),
        NodeSpec(
            'sim_stage',
            'activesurv_sim.sim_stage_node',
            parameters={'use_sim_time': True, 'motion_class': 'medium'},
        ),
    ]
    peer = rclpy_context.create_node('graph_peer')
    clocks: list[float] = []
    objects: list[ObjectState] = []
    joints: list[JointState] = []
    peer.create_subscription(
        Clock, '/clock', lambda m: clocks.append(m.clock.sec + 1e-9 * m.clock.nanosec), qos.CLOCK
    )
    peer.create_subscription(ObjectState, topics.OBJECT_STATE, objects.append, qos.STATE)
    peer.create_subscription(JointState, topics.joint_states('cam1'), joints.append, qos.STATE)
    try:
        with Launcher(specs, workdir=tmp_path) as launcher:
            assert spin_until(
                [peer],
                lambda: (
                    launcher.check() is None
                    and len(clocks) > 50
                    and len(joints) > 5
                    and len(objects) > 50
                ),
                timeout=30.0,
            )
            launcher.check()
    finally:
        peer.destroy_node()
    # Simulated time runs at about twice the wall clock and starts near 0.
    assert 0.0 <= clocks[0] < 5.0
    assert clocks[-1] > clocks[0]
    # The stage stamps its joint states with simulated time, not the wall clock.
    stamp = joints[-1].header.stamp.sec + 1e-9 * joints[-1].header.stamp.nanosec
    assert stamp < 1000.0
    # The object starts on the path's first point (0.17, 0.06) at start_time 0.5 s and moves
    # along it at up to 20 mm/s: the first state we receive (discovery may take a while on a
    # loaded machine) is no further from the start than that speed allows at its stamp.
    first = objects[0].top_marker
    t_first = objects[0].header.stamp.sec + 1e-9 * objects[0].header.stamp.nanosec
    moved = math.hypot(first.x - 0.17, first.y - 0.06)
    assert moved <= 0.020 * max(0.0, t_first - 0.5) + 1e-3, (moved, t_first)
    assert objects[-1].top_marker.x > first.x


def _state_stamps(peer: Any) -> list[float]:
    """The stamps of the object states ``peer`` hears from now on (filled as it spins)."""
    from activesurv_common.ros.conversions import time_to_sec
    from activesurv_interfaces.msg import ObjectState

    stamps: list[float] = []
    peer.create_subscription(
        ObjectState,
        topics.OBJECT_STATE,
        lambda m: stamps.append(time_to_sec(m.header.stamp)),
        qos.STATE,
    )
    return stamps


def _clock_stamps(peer: Any) -> list[float]:
    """The /clock ticks ``peer`` hears from now on (filled as it spins)."""
    from rosgraph_msgs.msg import Clock

    from activesurv_common.ros.conversions import time_to_sec

    ticks: list[float] = []
    peer.create_subscription(
        Clock, topics.CLOCK, lambda m: ticks.append(time_to_sec(m.clock)), qos.CLOCK
    )
    return ticks


@pytest.mark.graph
@pytest.mark.parametrize('instant_ticks', [True, False])
def test_xy_table_publishes_one_state_at_a_demand_instant(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool], instant_ticks: bool
) -> None:
    """A demand instant gets its own state (and, with ``instant_ticks``, its tick); the
    periodic state that would fall within a quarter period of it is skipped (every process
    would wake twice just when the cameras image). Without instant ticks the periodic tick
    is kept: simulated time never stands still for two periods."""
    from activesurv_common.ros.conversions import sec_to_time
    from activesurv_interfaces.msg import CaptureRequest
    from activesurv_launch.launcher import Launcher, NodeSpec

    rate = 20.0
    specs = [
        NodeSpec(
            'xy_table',
            'activesurv_sim.xy_table_node',
            parameters={
                'publish_rate': rate,
                'wait_for_subscribers': 1,
                'instant_ticks': instant_ticks,
            },
        )
    ]
    peer = rclpy_context.create_node('instant_peer')
    stamps = _state_stamps(peer)
    ticks = _clock_stamps(peer)
    requests = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS)
    instants: list[float] = []
    try:
        with Launcher(specs, workdir=tmp_path) as launcher:
            assert spin_until([peer], lambda: launcher.check() is None and len(stamps) > 5, 30.0)
            # Instants a tenth of a period past the periodic states' grid (the table starts
            # its time on a tick), 0.5 s ahead: the periodic state falls within a quarter
            # period of the instant's (and a periodic tick is not taken for an instant's).
            base = round(stamps[-1] * rate) / rate + 0.5 + 0.1 / rate
            for i in range(4):
                t = base + 0.25 * i
                instants.append(t)
                requests.publish(
                    CaptureRequest(demand_index=i, demand_instant=sec_to_time(t), camera_ids=['c'])
                )
            assert spin_until([peer], lambda: stamps[-1] > instants[-1] + 0.2, 30.0)
            launcher.check()
    finally:
        peer.destroy_node()
    for t in instants:
        near = [s for s in stamps if abs(s - t) < 0.25 / rate]
        assert near == [pytest.approx(t, abs=1e-6)], (t, near)
        near_ticks = [s for s in ticks if abs(s - t) < 0.25 / rate]
        assert len(near_ticks) == 1, (t, near_ticks)
        assert (abs(near_ticks[0] - t) < 1e-6) == instant_ticks, (t, near_ticks)
    gaps = [b - a for a, b in itertools.pairwise(ticks)]
    assert max(gaps) < 1.5 / rate, max(gaps)


@pytest.mark.graph
def test_xy_table_thins_its_clock_ticks_not_its_states(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """With ``clock_period`` the regular /clock ticks come at most once per that much
    simulated time (each wakes every process and timer), the object states at their rate."""
    from activesurv_launch.launcher import Launcher, NodeSpec

    rate, period = 20.0, 0.1
    parameters = {'publish_rate': rate, 'wait_for_subscribers': 1, 'clock_period': period}
    specs = [NodeSpec('xy_table', 'activesurv_sim.xy_table_node', parameters=parameters)]
    peer = rclpy_context.create_node('thin_peer')
    stamps = _state_stamps(peer)
    ticks = _clock_stamps(peer)
    try:
        with Launcher(specs, workdir=tmp_path) as launcher:
            assert spin_until([peer], lambda: launcher.check() is None and len(stamps) > 30, 30.0)
            launcher.check()
    finally:
        peer.destroy_node()
    # Time held at 0 until the peer was heard; its first tick as it starts may come late.
    running = [t for t in ticks if t > 0.0][1:]
    tick_gaps = [b - a for a, b in itertools.pairwise(running)]
    state_gaps = [b - a for a, b in itertools.pairwise(stamps)]
    assert len(tick_gaps) >= 8, ticks
    assert min(tick_gaps) >= period - 1e-5, tick_gaps
    assert max(tick_gaps) < period + 1.5 / rate, tick_gaps  # no tick lost beyond the thinning
    assert sorted(state_gaps)[len(state_gaps) // 2] == pytest.approx(1.0 / rate, abs=0.01)


@pytest.mark.graph
def test_a_stage_keeps_its_rate_on_the_tables_grid_between_thinned_ticks(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """The graph ticks /clock on every other state; a simulated stage still publishes its
    states at its own rate, on the table's grid (its mapping and phase on
    ``/sim/clock_origin``), not on the ticks."""
    from sensor_msgs.msg import JointState

    from activesurv_common.ros.conversions import time_to_sec
    from activesurv_launch.launcher import Launcher, NodeSpec

    rate, phase = 10.0, 0.05
    table = {
        'publish_rate': rate,
        'publish_phase': phase,
        'clock_period': 2.0 / rate,
        'wait_for_subscribers': 1,
    }
    stage = {'use_sim_time': True, 'publish_rate': rate, 'motion_class': 'medium'}
    specs = [
        NodeSpec('xy_table', 'activesurv_sim.xy_table_node', parameters=table),
        NodeSpec('sim_stage', 'activesurv_sim.sim_stage_node', parameters=stage),
    ]
    peer = rclpy_context.create_node('stage_grid_peer')
    _state_stamps(peer)  # the table's one reader: time starts once it is heard
    ticks = _clock_stamps(peer)
    states: list[float] = []
    peer.create_subscription(
        JointState,
        topics.joint_states('cam1'),
        lambda m: states.append(time_to_sec(m.header.stamp)),
        qos.STATE,
    )
    try:
        with Launcher(specs, workdir=tmp_path) as launcher:
            assert spin_until(
                [peer],
                lambda: launcher.check() is None and sum(t > 0.5 for t in states) > 30,
                timeout=40.0,
            )
    finally:
        peer.destroy_node()
    running = [t for t in ticks if t > 0.0]
    on_grid = [t for t in states if t > 0.3 + running[0]]  # once the mapping is known
    assert len(on_grid) >= 20, states
    gaps = [b - a for a, b in itertools.pairwise(on_grid)]
    assert max(gaps) < 1.5 / rate, gaps  # its rate, not the ticks'
    assert min(gaps) > 0.5 / rate, gaps
    assert all(abs((t - phase) * rate - round((t - phase) * rate)) < 1e-6 for t in on_grid)
    tick_gaps = [b - a for a, b in itertools.pairwise(running)]
    assert min(tick_gaps) >= 2.0 / rate - 1e-5, tick_gaps  # the ticks were thinned


@pytest.mark.graph
def test_xy_table_keeps_its_states_on_a_phased_grid(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """With ``publish_phase`` the periodic states (and ticks) fall at phase + n / rate, one per
    period, whatever the timer's own phase (the graph puts them on the overhead camera's
    frames, half a period off the demand instants)."""
    from activesurv_launch.launcher import Launcher, NodeSpec

    rate, phase = 10.0, 0.05
    specs = [
        NodeSpec(
            'xy_table',
            'activesurv_sim.xy_table_node',
            parameters={'publish_rate': rate, 'publish_phase': phase, 'wait_for_subscribers': 1},
        )
    ]
    peer = rclpy_context.create_node('phase_peer')
    stamps = _state_stamps(peer)
    try:
        with Launcher(specs, workdir=tmp_path) as launcher:
            assert spin_until([peer], lambda: launcher.check() is None and len(stamps) > 15, 30.0)
    finally:
        peer.destroy_node()
    periods = [(s - phase) * rate for s in stamps[1:]]  # the first: as time starts
    # Each on its grid point (late by the timer's wake-up at most a quarter period), one a period.
    assert all(-0.25 <= p - round(p) < 0.25 for p in periods), stamps
    assert len({round(p) for p in periods}) == len(periods), stamps


@pytest.mark.graph
def test_a_held_xy_table_starts_time_only_when_released(
    tmp_path: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """Started with the graph (``hold_until_released``), the table holds time at 0 with its
    readers all matched, past its ``wait_timeout`` too, until the orchestrator's latched
    release; then time runs."""
    import time

    from std_msgs.msg import Empty

    from activesurv_launch.launcher import Launcher, NodeSpec

    parameters = {
        'publish_rate': 10.0,
        'wait_for_subscribers': 1,
        'wait_timeout': 0.5,
        'hold_until_released': True,
    }
    specs = [NodeSpec('xy_table', 'activesurv_sim.xy_table_node', parameters=parameters)]
    peer = rclpy_context.create_node('held_peer')
    ticks = _clock_stamps(peer)
    stamps = _state_stamps(peer)
    try:
        with Launcher(specs, workdir=tmp_path) as launcher:
            # Held: ticks at 0 (the table is up and heard), no state, for well past the timeout.
            assert spin_until([peer], lambda: launcher.check() is None and len(ticks) > 5, 30.0)
            end = time.monotonic() + 1.5
            spin_until([peer], lambda: time.monotonic() > end, 3.0)
            assert set(ticks) == {0.0}
            assert not stamps
            release = peer.create_publisher(Empty, topics.TIME_RELEASE, qos.LATCHED)
            release.publish(Empty())
            assert spin_until([peer], lambda: len(stamps) > 5 and max(ticks) > 0.4, 20.0)
            launcher.check()
    finally:
        peer.destroy_node()
