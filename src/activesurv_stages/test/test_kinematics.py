"""Kinematics core: limits are never exceeded, moves end at their goals (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_stages.config import MOTION_CLASSES, motion_class
from activesurv_stages.errors import ConfigError, LimitError
from activesurv_stages.kinematics import (
    AxisLimits,
    AxisSimulator,
    min_travel_time,
    plan_move,
    reachable_distance,
    stop_move,
)


def _sample(move: object, t_end: float, n: int = 1500) -> tuple[np.ndarray, np.ndarray]:
    ts = np.linspace(0.0, t_end, n)
    st_ = np.array([move.state(t) for t in ts])  # type: ignore[attr-defined]
    return ts, st_


@settings(max_examples=300, deadline=None)
@given(
    st.floats(-1, 1),
    st.floats(-1, 1),
    st.floats(-0.3, 0.3),
    st.floats(0.005, 0.3),
    st.floats(0.02, 2.0),
)
def test_moves_respect_limits_and_end_at_goal(
    p0: float, goal: float, v0: float, v_max: float, a_max: float
) -> None:
    m = plan_move(0.0, p0, v0, goal, v_max, a_max)
    ts, s = _sample(m, m.duration + 0.5)
    dv = np.diff(s[:, 1]) / np.diff(ts)
    assert np.max(np.abs(dv)) <= a_max * (1 + 1e-6)
    braking = abs(v0) > v_max  # starts above the cap: only braking until it is under it
    t_cap = (abs(v0) - v_max) / a_max if braking else 0.0
    assert np.max(np.abs(s[ts > t_cap + 1e-9, 1])) <= v_max * (1 + 1e-6)
    assert m.state(m.end_time + 1.0) == (goal, 0.0)
    p_end, v_end = m.state(m.end_time)
    assert p_end == pytest.approx(goal, abs=1e-9)
    assert v_end == pytest.approx(0.0, abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(0.005, 0.3), st.floats(0.02, 2.0))
def test_travel_time_and_reach_are_inverse(d: float, v_max: float, a_max: float) -> None:
    t = min_travel_time(d, v_max, a_max)
    assert reachable_distance(t, v_max, a_max) == pytest.approx(d, abs=1e-9)
    assert plan_move(0.0, 0.0, 0.0, d, v_max, a_max).duration == pytest.approx(t, abs=1e-9)


def test_replanning_mid_move_and_stop() -> None:
    lim = AxisLimits(-0.15, 0.15, 0.025, 0.1)
    ax = AxisSimulator(lim, 0.0, 0.0)
    ax.command(0.0, 0.1)
    _, v = ax.state(1.0)
    assert v == pytest.approx(0.025)
    ax.command(1.0, -0.1)  # reverse while moving: brakes first, never exceeds the limits
    ts, s = _sample(ax.move, 20.0)
    assert np.max(np.abs(np.diff(s[:, 1]) / np.diff(ts))) <= 0.1 * (1 + 1e-6)
    assert ax.state(30.0) == (-0.1, 0.0)
    ax.command(30.0, 0.1)
    m = ax.stop(31.0)
    assert m.state(100.0)[1] == 0.0
    assert stop_move(0.0, 1.0, 0.0, 1.0).duration == 0.0


def test_soft_limits_and_invalid_values() -> None:
    lim = AxisLimits(-0.15, 0.15, 0.025, 0.1, resolution=1e-6)
    assert lim.check_position(0.1000004) == pytest.approx(0.1)
    with pytest.raises(LimitError, match='outside the soft limits'):
        lim.check_position(0.2)
    with pytest.raises(LimitError, match='finite'):
        lim.check_position(float('nan'))
    assert lim.check_velocity(None) == 0.025
    assert lim.check_velocity(1.0) == 0.025
    with pytest.raises(LimitError):
        lim.check_velocity(-1.0)
    with pytest.raises(LimitError):
        AxisLimits(1.0, -1.0, 0.1, 0.1)
    with pytest.raises(LimitError):
        AxisSimulator(lim).command(0.0, 1.0)


def test_motion_classes() -> None:
    assert not MOTION_CLASSES['static'].moves
    assert motion_class('medium').limits('linear')[0] == pytest.approx(0.010)
    assert motion_class('fast').limits('rotary')[0] == pytest.approx(0.2)
    with pytest.raises(ConfigError, match='unknown motion class'):
        motion_class('warp')
