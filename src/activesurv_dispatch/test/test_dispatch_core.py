"""Core tests of the dispatching (no ROS): visibility, best achievable pose, assignment,
preassignment, replanning, motion control and initial-pose determination."""

from __future__ import annotations

import math
from itertools import pairwise
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.best_pose import (
    Candidate,
    Target,
    aim_yaw,
    best_achievable_pose,
    reachable_box,
    view_batch,
)
from activesurv_dispatch.errors import DispatchConfigError
from activesurv_dispatch.initial_pose import initial_poses
from activesurv_dispatch.motion import CaptureScheduler, MotionController
from activesurv_dispatch.planner import Demand, DispatchPlanner, Role
from activesurv_dispatch.sensors import load_setup
from activesurv_dispatch.visibility import fused_visibility, single_visibility

MODEL = SensorModel.load()
NORMAL = np.array([0.0, -1.0, 0.0])
COV = np.diag([4e-6, 4e-6, 2.5e-7, 1e-4, 1e-4, 1e-4])  # 2 mm prediction std in x, y


def _demand(j: int, t: float, x: float, y: float = 0.05) -> Demand:
    return Demand(j, t, np.array([x, y, 0.05]), NORMAL, COV)


# -- visibility ----------------------------------------------------------------------------
def test_visibility_is_eq_1_and_2() -> None:
    R = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]) * 1e-8
    assert single_visibility(R) == pytest.approx(1.0 / np.linalg.norm(R, 'fro'))
    assert fused_visibility([R]) == pytest.approx(single_visibility(R))
    # Three identical sensors: P = R / 3.
    assert fused_visibility([R, R, R]) == pytest.approx(3.0 * single_visibility(R))
    assert fused_visibility([]) == 0.0
    A = np.array([[2.0, 0.5], [0.5, 1.0]])  # any square matrix
    B = np.array([[1.0, 0.0], [0.0, 3.0]])
    # By hand: A^-1 + B^-1 = [[11/7, -2/7], [-2/7, 31/21]], so P = [[31, 6], [6, 33]] / 47
    # and ||P||_F = sqrt(31^2 + 2 * 6^2 + 33^2) / 47 = sqrt(2122) / 47.
    assert fused_visibility([A, B]) == pytest.approx(47.0 / math.sqrt(2122.0))
    with pytest.raises(ValueError, match='square'):
        single_visibility(np.zeros((2, 3)))
    with pytest.raises(ValueError, match='NaN'):
        fused_visibility([np.full((2, 2), np.nan)])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(1e-9, 1e-3), min_size=6, max_size=6), st.integers(1, 5))
def test_more_sensors_never_see_less(diag: list[float], n: int) -> None:
    R = np.diag(diag)
    vis = [fused_visibility([R] * m) for m in range(1, n + 1)]
    assert all(b >= a * (1 - 1e-9) for a, b in pairwise(vis))


# -- best achievable pose ------------------------------------------------------------------
@pytest.mark.parametrize('motion', ['medium', 'fast'])
def test_best_achievable_pose_is_reachable_and_best(motion: str) -> None:
    setup = load_setup(motion=motion)
    s = setup.sensor('cam1')
    q0 = np.array([0.05, -0.5])
    target = Target(np.array([0.24, 0.06, 0.05]), NORMAL)
    dt = 3.0
    best = best_achievable_pose(s, q0, target, dt, MODEL, setup.marker_radius)
    lo, hi = reachable_box(s, q0, dt)
    assert np.all(best.joints >= lo - 1e-12)
    assert np.all(best.joints <= hi + 1e-12)
    assert best.in_view
    # Brute force over the reachable box: nothing is more than 1 % better.
    grid = np.array(
        [[a, b] for a in np.linspace(lo[0], hi[0], 61) for b in np.linspace(lo[1], hi[1], 241)]
    )
    vis = view_batch(s, grid, target, setup.marker_radius, MODEL)[0]
    assert best.visibility >= 0.99 * vis.max()


def test_static_camera_cannot_move() -> None:
    setup = load_setup(motion='static')
    s = setup.sensor('cam2')
    target = Target(np.array([0.24, 0.06, 0.05]), NORMAL)
    best = best_achievable_pose(s, np.array([0.3]), target, 10.0, MODEL, setup.marker_radius)
    assert best.joints == pytest.approx([0.3])


# -- assignment, preassignment, replanning -------------------------------------------------
def _aimed_joints(setup_motion: str, x: float) -> dict[str, np.ndarray]:
    """Every camera already pointing at a target at (x, 0.05): the best it can do in no time."""
    setup = load_setup(motion=setup_motion)
    target = Target(np.array([x, 0.05, 0.05]), NORMAL)
    out = {}
    for s in setup.sensors:
        q0 = setup.initial[s.camera_id]
        out[s.camera_id] = best_achievable_pose(s, q0, target, 100.0, MODEL, 0.0125).joints
    return out


def test_assignment_picks_the_k_best_and_preassigns_the_rest() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3)
    demands = [_demand(0, 2.0, 0.25), _demand(1, 3.0, 0.27), _demand(2, 4.0, 0.29)]
    plan = planner.plan(0.0, demands, joints)
    assigned = plan.assigned()
    assert len(assigned) == 3
    # The ranking is by visibility at the best achievable pose, and the top 3 are assigned.
    ranked = [c for c, _ in plan.ranking]
    assert set(assigned) == set(ranked[:3])
    vis = dict(plan.ranking)
    assert min(vis[c] for c in assigned) >= vis[ranked[3]]
    rest = ranked[3]
    assert plan.assignments[rest].role is Role.PREASSIGNED
    assert plan.assignments[rest].demand_index == 1
    assert plan.fused_visibility > max(vis.values())  # fusing three beats the best single one


def test_assignment_is_frozen_until_serviced() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3)
    d0 = _demand(0, 2.0, 0.25)
    first = planner.plan(0.0, [d0, _demand(1, 3.0, 0.27)], joints).assigned()
    # A much better position for another camera does not change the frozen subset.
    later = planner.plan(0.5, [d0, _demand(1, 3.0, 0.27)], _aimed_joints('fast', 0.20))
    assert later.assigned() == first
    planner.serviced(0)
    after = planner.plan(2.1, [_demand(1, 3.0, 0.27)], joints)
    assert after.first_index == 1


def test_replanning_only_outside_the_uncertainty_box() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3, rho=1.0)
    plan0 = planner.plan(0.0, [_demand(0, 3.0, 0.25)], joints)
    inside = planner.plan(0.2, [_demand(0, 3.0, 0.25 + 0.001)], joints)  # 1 mm < 2 mm sigma
    assert not inside.replanned
    assert planner.replans == 0
    moved = planner.plan(0.4, [_demand(0, 3.0, 0.25 + 0.01)], joints)  # 10 mm > 2 mm sigma
    assert moved.replanned
    assert planner.replans == 1
    assert moved.assigned() == plan0.assigned()  # same subset, new poses
    cam = next(c for c in moved.assigned() if setup.sensor(c).has_linear)
    assert not np.allclose(moved.assignments[cam].desired, plan0.assignments[cam].desired)


def test_a_plan_weighs_each_frozen_view_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """A plan that keeps its frozen assignment asks the same view of each frozen pose three
    times (is a replan needed, is the old pose better, the fused visibility): it is weighed
    once, and the plan's figure is the evaluation's."""
    from activesurv_dispatch import best_pose
    from activesurv_dispatch import planner as planner_module

    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3, rho=1.0)
    planner.plan(0.0, [_demand(0, 3.0, 0.25)], joints)
    weighed: list[tuple[str, bytes]] = []
    real = best_pose.view_one

    def counted(sensor: Any, q: Any, *args: Any, **kwargs: Any) -> Any:
        weighed.append((sensor.camera_id, np.asarray(q).tobytes()))
        return real(sensor, q, *args, **kwargs)

    monkeypatch.setattr(planner_module, 'view_one', counted)
    d0 = _demand(0, 3.0, 0.25 + 0.001)  # inside the box: kept, not replanned
    plan = planner.plan(0.2, [d0], joints)
    assert not plan.replanned
    assert len(plan.assigned()) == 3
    assert len(weighed) == len(set(weighed)), f'views weighed more than once: {weighed}'
    poses = {c: plan.assignments[c].desired for c in plan.assigned()}
    expected = best_pose.visibility_at_poses(
        {s.camera_id: s for s in setup.sensors}, MODEL, poses, d0.target, setup.marker_radius
    )
    assert plan.fused_visibility == expected
    # A new plan weighs its views again (the prediction may have moved).
    weighed.clear()
    planner.plan(0.3, [d0], joints)
    assert weighed


def test_a_manoeuvre_replans_inside_the_box() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3, rho=1.0)
    planner.plan(0.0, [_demand(0, 3.0, 0.25)], joints)
    planner.manoeuvre()  # the predictor saw the object stop or start
    replanned = planner.plan(0.2, [_demand(0, 3.0, 0.25 + 0.001)], joints)  # inside the box
    assert replanned.replanned
    assert planner.replans == 1
    again = planner.plan(0.3, [_demand(0, 3.0, 0.25 + 0.001)], joints)
    assert not again.replanned  # one manoeuvre, one replan


def test_the_session_replans_when_the_manoeuvre_count_changes() -> None:
    from activesurv_dispatch.session import Dispatcher, DispatcherConfig

    setup = load_setup(motion='fast')
    session = Dispatcher(setup, MODEL, DispatcherConfig())
    for c, q in _aimed_joints('fast', 0.25).items():
        session.on_joints(c, q, 0.0)
    session.set_horizon([_demand(0, 3.0, 0.25)], 0.0, manoeuvres=0)
    same = session.set_horizon([_demand(0, 3.0, 0.25)], 0.1, manoeuvres=0)
    assert same.plan is not None
    assert not same.plan.replanned
    out = session.set_horizon([_demand(0, 3.0, 0.25)], 0.2, manoeuvres=1)
    assert out.plan is not None
    assert out.plan.replanned
    assert any('manoeuvred' in text for _, text in out.events)
    assert session.counts['manoeuvres'] == 1


def test_dead_camera_is_not_dispatched() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3)
    d0 = _demand(0, 2.0, 0.25)
    first = planner.plan(0.0, [d0], joints).assigned()
    planner.exclude(first[0])
    again = planner.plan(0.1, [d0], joints)
    assert first[0] not in again.assigned()
    assert first[0] not in again.assignments


def test_planner_rejects_bad_parameters() -> None:
    setup = load_setup(motion='fast')
    with pytest.raises(DispatchConfigError):
        DispatchPlanner(setup, MODEL, k=0)
    with pytest.raises(DispatchConfigError):
        DispatchPlanner(setup, MODEL, rho=math.nan)


# -- motion control and capture timing -----------------------------------------------------
def test_motion_deadband_holding_and_capture_timing() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3)
    d0 = _demand(0, 2.0, 0.25)
    plan = planner.plan(0.0, [d0], joints)
    mc = MotionController(setup)
    cmds = mc.commands(plan, {0: d0})
    assert {c.camera_id for c in cmds} == set(plan.assigned())
    for c in cmds:
        lims = setup.sensor(c.camera_id).limits
        assert list(c.max_velocities) == [lim.max_velocity for lim in lims]
        assert c.arrival_time == 2.0
    assert mc.commands(plan, {0: d0}) == []  # unchanged: nothing sent again
    sched = CaptureScheduler(lead=0.3)
    assert sched.due(1.6, plan, {0: d0}) is None
    cap = sched.due(1.75, plan, {0: d0})
    assert cap is not None
    assert set(cap.cameras) == set(plan.assigned())
    assert sched.due(1.8, plan, {0: d0}) is None  # once
    assert sched.newly_serviced(1.9) == []
    assert [c.demand.index for c in sched.newly_serviced(2.0)] == [0]


# -- initial poses -------------------------------------------------------------------------
def _expected() -> list[Demand]:
    xs = np.linspace(0.19, 0.31, 10)
    return [
        _demand(j, 2.0 + j, float(x), 0.05 + 0.05 * (1 - ((x - 0.25) / 0.06) ** 2))
        for j, x in enumerate(xs)
    ]


def test_static_initial_poses_cover_every_demand_twice() -> None:
    setup = load_setup(motion='static')
    poses = initial_poses(setup, MODEL, _expected())
    counts = np.zeros(10, dtype=int)
    for s in setup.sensors:
        for j, d in enumerate(_expected()):
            counts[j] += bool(
                view_batch(s, poses[s.camera_id][None, :], d.target, 0.0125, MODEL)[3][0]
            )
    assert counts.min() >= 2


def test_moving_initial_poses_see_the_first_demands() -> None:
    for motion in ('medium', 'fast'):
        setup = load_setup(motion=motion)
        poses = initial_poses(setup, MODEL, _expected()[:4])
        seeing = sum(
            best_achievable_pose(
                s, poses[s.camera_id], _expected()[0].target, 2.0, MODEL, 0.0125
            ).in_view
            for s in setup.sensors
        )
        assert seeing >= 3, motion


def test_missed_demands_are_reported_not_dropped() -> None:
    sched = CaptureScheduler(lead=0.3)
    d0, d1 = _demand(0, 2.0, 0.25), _demand(1, 3.0, 0.26)
    missed = sched.missed(2.5, {0: d0, 1: d1})
    assert [(c.demand.index, c.cameras) for c in missed] == [(0, ())]
    assert sched.missed(2.6, {0: d0, 1: d1}) == []  # once


def test_short_assignment_is_topped_up_until_its_capture() -> None:
    """A camera whose first stage state comes after the assignment (or a dead camera's slot) is
    filled from the spare cameras, never by swapping one in the assignment, and not once the
    capture request has gone out."""
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    full = DispatchPlanner(setup, MODEL, k=3).plan(0.0, [_demand(0, 2.0, 0.25)], joints)
    best = full.assigned()
    late = best[0]  # the best camera is heard only later
    planner = DispatchPlanner(setup, MODEL, k=3)
    d0 = _demand(0, 2.0, 0.25)
    without = {c: q for c, q in joints.items() if c != late}
    first = planner.plan(0.0, [d0], without).assigned()
    assert late not in first
    assert len(first) == 3  # three of the other three
    # cam `late` appears: the assignment is full, so nothing changes.
    assert planner.plan(0.1, [d0], joints).assigned() == first

    # Now one assigned camera dies: its slot goes to the best spare one, `late`.
    dead = first[-1]
    planner.exclude(dead)
    topped = planner.plan(0.2, [d0], joints).assigned()
    assert dead not in topped
    assert set(first) - {dead} <= set(topped)
    assert late in topped
    assert len(topped) == 3

    # After the capture request no camera is added any more.
    planner2 = DispatchPlanner(setup, MODEL, k=3)
    first2 = planner2.plan(0.0, [d0], without).assigned()
    planner2.close(0)
    planner2.exclude(first2[0])
    closed = planner2.plan(1.8, [d0], joints).assigned()
    assert len(closed) == 2
    assert late not in closed


def test_assignment_with_too_few_cameras_fills_up_when_they_are_heard() -> None:
    setup = load_setup(motion='fast')
    joints = _aimed_joints('fast', 0.25)
    planner = DispatchPlanner(setup, MODEL, k=3)
    d0 = _demand(0, 2.0, 0.25)
    two = dict(list(joints.items())[:2])
    first = planner.plan(0.0, [d0], two).assigned()
    assert len(first) <= 2
    later = planner.plan(0.3, [d0], joints).assigned()
    assert set(first) <= set(later)
    assert len(later) == 3


def test_a_replan_that_sees_nothing_keeps_the_pose_that_points_nearer() -> None:
    # Two objects at once: a camera swung from one object to the other is planned at the edge
    # of what it can reach; replanned from where it is on the way, the new best pose lies
    # short of the old one and neither is sure to see the marker. Re-aiming short pulled the
    # camera back 3-5 degrees from the target; the pose that points nearer to it stays.
    setup = load_setup(motion='fast')
    planner = DispatchPlanner(setup, MODEL, k=3, rho=1.0)
    wide = np.diag([4e-4, 4e-4, 2.5e-7, 1e-4, 1e-4, 1e-4])  # 20 mm: never sure to be in view
    demand = Demand(0, 3.0, np.array([0.22, 0.10, 0.05]), NORMAL, wide)
    cam = next(s for s in setup.sensors if not s.has_linear)
    aim = float(aim_yaw(cam, np.zeros(1), demand.target)[0])
    near = Candidate(np.array([aim - 0.04]), 0.0, math.nan, math.nan, False)
    short = Candidate(np.array([aim - 0.08]), 0.0, math.nan, math.nan, False)
    assert view_batch(cam, near.joints[None, :], demand.target, 0.0125, MODEL)[0][0] == 0.0
    kept = planner._better(cam.camera_id, near, short, demand)
    assert np.allclose(kept.joints, near.joints)
    # ... and the other way round: a new pose nearer to the target replaces an old one.
    moved = planner._better(cam.camera_id, short, near, demand)
    assert np.allclose(moved.joints, near.joints)
    # A new pose that sees the marker always wins over one that does not.
    sharp = Demand(0, 3.0, demand.position, NORMAL, COV)
    seeing = best_achievable_pose(cam, np.array([aim]), sharp.target, 0.0, MODEL, 0.0125)
    assert seeing.visibility > 0.0
    assert np.allclose(planner._better(cam.camera_id, near, seeing, sharp).joints, aim)


def test_the_best_pose_prefers_a_view_in_focus_and_across_less_motion() -> None:
    """cam1 on its linear stage sees the target from 0.53 to 0.71 m and likes 0.56 m best
    without optics; with its lens at f/2 focused at 0.60 or 0.68 m the best view moves to the
    distance in focus; a fast target's streak lowers the views' visibility."""
    from dataclasses import replace

    setup = load_setup(motion='fast')
    s = setup.sensor('cam1')
    q0 = np.array([0.15, -0.5])
    target = Target(np.array([0.24, 0.06, 0.05]), NORMAL)
    lims = s.limits
    grid = np.array(
        [
            [a, b]
            for a in np.linspace(lims[0].min_position, lims[0].max_position, 31)
            for b in np.linspace(lims[1].min_position, lims[1].max_position, 121)
        ]
    )
    plain = view_batch(s, grid, target, setup.marker_radius, MODEL)
    assert abs(plain[1][int(np.argmax(plain[0]))] - 0.56) < 0.01
    for focus in (0.60, 0.68):
        cam = replace(s.camera, f_number=2.0, focus_distance=focus, focal_length=0.025)
        lensed = replace(s, camera=cam)
        vis, d, _, _ = view_batch(lensed, grid, target, setup.marker_radius, MODEL)
        assert np.all(vis <= plain[0] + 1e-18)  # blur never helps
        assert abs(d[int(np.argmax(vis))] - focus) < 0.015
        found = best_achievable_pose(lensed, q0, target, 3.0, MODEL, setup.marker_radius)
        assert found.in_view
        assert abs(found.distance - focus) < 0.03
    exposed = replace(s, camera=replace(s.camera, exposure_time=0.02))
    fast = Target(target.position, NORMAL, 0.0, np.array([0.3, 0.0, 0.0]))
    slow = Target(target.position, NORMAL, 0.0, np.array([0.0, 0.0, 0.0]))
    v_fast = view_batch(exposed, grid, fast, setup.marker_radius, MODEL)[0]
    v_slow = view_batch(exposed, grid, slow, setup.marker_radius, MODEL)[0]
    assert np.all(v_fast <= v_slow + 1e-18)
    assert v_fast.max() < v_slow.max()


@pytest.mark.parametrize('hold', [0.0, 0.05])
def test_cameras_hold_still_past_the_instant_for_the_capture_hold(hold: float) -> None:
    """Free-running cameras (a rig): the frame nearest the instant may come after it, and the
    demand's cameras stay still until ``instant + capture_hold``; then they are free again."""
    from activesurv_dispatch.session import Dispatcher, DispatcherConfig, Outputs

    setup = load_setup(motion='fast')
    session = Dispatcher(setup, MODEL, DispatcherConfig(capture_hold=hold))
    aimed = _aimed_joints('fast', 0.25)

    def tick(now: float) -> Outputs:
        out = Outputs()
        for c, q in aimed.items():  # the stages keep reporting (alive)
            out.merge(session.on_joints(c, q, now))
        out.merge(session.tick(now))
        return out

    tick(1.0)
    session.set_horizon([_demand(0, 2.0, 0.25), _demand(1, 3.0, 0.31)], 1.0)
    (capture,) = tick(1.85).captures  # (a grace past the lead: no fresher fix)
    assert set(capture.cameras) <= session.motion.holding
    out = tick(2.0 + 0.5 * hold)
    assert [s.demand.index for s in out.serviced] == [0]
    held = set(capture.cameras) & session.motion.holding
    assert held == (set(capture.cameras) if hold else set())
    assert not any(g.camera_id in held for g in out.goals)  # no held camera is moved
    tick(2.0 + hold + 1e-6)
    assert not set(capture.cameras) & session.motion.holding


def test_the_log_says_which_views_lost_to_their_blur() -> None:
    """A marker streaking across a camera's view over a long exposure costs that view
    visibility (the sensor model's blur factor); the assignment's log line says how much."""
    from dataclasses import replace

    from activesurv_dispatch.session import BLUR_SAID, Dispatcher, DispatcherConfig

    assert MODEL.models_blur
    setup = load_setup(motion='fast')
    slow = replace(
        setup,
        sensors=tuple(
            replace(s, camera=replace(s.camera, exposure_time=0.03)) for s in setup.sensors
        ),
    )
    joints = _aimed_joints('fast', 0.25)
    still = DispatchPlanner(slow, MODEL, k=3).plan(0.0, [_demand(0, 2.0, 0.25)], joints)
    assert all(loss < BLUR_SAID for _, loss in still.blur_loss)
    moving = replace(_demand(0, 2.0, 0.25), velocity=np.array([0.3, 0.0, 0.0]))
    plan = DispatchPlanner(slow, MODEL, k=3).plan(0.0, [moving], joints)
    lost = {c: loss for c, loss in plan.blur_loss if loss >= BLUR_SAID}
    assert lost, plan.blur_loss
    session = Dispatcher(slow, MODEL, DispatcherConfig())
    for c, q in joints.items():
        session.on_joints(c, q, 0.0)
    out = session.set_horizon([moving], 0.0)
    (said,) = [text for _, text in out.events if 'assigned' in text]
    assert any(f'{c} ' in said and '(blur -' in said for c in lost), said


@pytest.mark.parametrize('quiet', [0.0, 0.05])
def test_a_serviced_demands_cameras_are_planned_after_the_replan_quiet(quiet: float) -> None:
    """At a demand's instant its frames are imaged and fused; the plan that frees its cameras
    (milliseconds of CPU) waits ``replan_quiet`` past the instant (0: at once, as lockstep)."""
    from activesurv_dispatch.session import Dispatcher, DispatcherConfig, Outputs

    setup = load_setup(motion='fast')
    session = Dispatcher(setup, MODEL, DispatcherConfig(replan_quiet=quiet))
    aimed = _aimed_joints('fast', 0.25)

    def tick(now: float) -> Outputs:
        for c, q in aimed.items():
            session.on_joints(c, q, now)
        return session.tick(now)

    tick(1.0)
    session.set_horizon([_demand(0, 2.0, 0.25), _demand(1, 3.0, 0.31)], 1.0)
    tick(1.85)
    out = tick(2.0)
    assert [s.demand.index for s in out.serviced] == [0]
    assert (out.plan is None) == (quiet > 0.0)  # planned at the instant only without a quiet
    if quiet:
        assert tick(2.0 + 0.5 * quiet).plan is None
        later = tick(2.0 + quiet)
        assert later.plan is not None
        assert later.plan.first_index == 1
