"""The first demand as lockstep and the graph both decide it (no ROS): a short first assignment
is made up from cameras that head for it, and the capture request waits for the plan on the
overhead frame taken at ``capture_lead`` before the instant."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.planner import Demand, DispatchPlanner, Role
from activesurv_dispatch.sensors import load_setup
from activesurv_dispatch.session import Dispatcher, DispatcherConfig

NORMAL = np.array([0.0, -1.0, 0.0])
COV = np.diag([4e-6, 4e-6, 2.5e-7, 1e-4, 1e-4, 1e-4])


def _demand(j: int, t: float, x: float) -> Demand:
    return Demand(j, t, np.array([x, 0.02, 0.05]), NORMAL, COV)


def test_cameras_missing_from_a_short_first_assignment_head_for_the_first_demand() -> None:
    setup = load_setup(motion='medium')
    planner = DispatchPlanner(setup, SensorModel.load(), k=3)
    # Every camera turned well away from the first demand, and little time to turn back: not
    # every camera can see it by then.
    joints = {c: q - np.eye(len(q))[-1] * 0.5 for c, q in setup.initial.items()}
    first, later = _demand(0, 1.1, 0.13), _demand(1, 2.1, 0.16)
    plan = planner.plan(0.5, [first, later], joints)
    assigned = plan.assigned()
    assert 0 < len(assigned) < 3, 'the set-up must leave this assignment short'
    standby = [
        c
        for c, a in plan.assignments.items()
        if a.role is Role.PREASSIGNED and a.demand_index == 0
    ]
    moving = [c for c in standby if setup.sensor(c).moves]
    assert moving, 'the missing cameras head for the first demand, not for later ones'
    assert len(assigned) + len(standby) <= 3
    # Their poses see the first demand (from wherever they are reached soonest).
    for c in standby:
        q = plan.assignments[c].desired
        assert planner.fused_visibility(first, {c: q}) > 0.0
        lims = setup.sensor(c).limits
        assert all(
            lim.min_position <= v <= lim.max_position for lim, v in zip(lims, q, strict=True)
        )


def test_a_capture_request_waits_for_the_plan_on_the_frame_at_its_lead() -> None:
    setup = load_setup(motion='fast')
    d = Dispatcher(setup, SensorModel.load(), DispatcherConfig(capture_lead=0.3))
    for c, q in setup.initial.items():
        d.on_joints(c, q, 0.0)
    demand = _demand(0, 1.5, 0.13)
    d.set_horizon([demand], 1.15, stamp=1.1)
    for c, q in setup.initial.items():
        d.on_joints(c, q, 1.2)
    # Due at 1.2 s, but the newest plan rests on the frame of 1.1 s: it waits ...
    assert not d.tick(1.2).captures
    # ... for the plan on the frame of 1.2 s, which sends it at once,
    out = d.set_horizon([demand], 1.25, stamp=1.2)
    assert [c.demand.index for c in out.captures] == [0]
    # and without such a plan it goes capture_grace later all the same.
    e = Dispatcher(setup, SensorModel.load(), DispatcherConfig(capture_grace=0.1))
    for c, q in setup.initial.items():
        e.on_joints(c, q, 1.25)
    e.set_horizon([demand], 1.15, stamp=1.1)
    assert not e.tick(1.25).captures
    assert [c.demand.index for c in e.tick(1.3).captures] == [0]


def test_another_object_in_front_of_the_marker_blocks_the_cameras_behind_it() -> None:
    """Object 2's plate, predicted between the cameras and object 1's marker at its instant,
    takes away the visibility of the cameras whose line of sight it cuts (eq. 1, occluded)."""
    setup = load_setup(motion='fast')
    planner = DispatchPlanner(setup, SensorModel.load(), k=3)
    joints = {c: q.copy() for c, q in setup.initial.items()}
    mine = Demand(0, 2.0, np.array([0.25, 0.10, 0.05]), NORMAL, COV, object_id=1)
    other = Demand(
        1,
        2.5,
        np.array([0.25, 0.01, 0.05]),
        NORMAL,
        COV,
        object_id=2,
        velocity=np.array([0.0, 0.04, 0.0]),  # at 2.0 s it is at y = -0.01 ... 0.03
    )
    alone = dict(planner.rank(mine, list(joints), joints, 0.0))
    planner.plan(0.0, [mine, other], joints)
    crowded = dict(planner.rank(mine, list(joints), joints, 0.0))
    lost = [c for c in joints if alone[c].visibility > 0.0 and crowded[c].visibility == 0.0]
    assert lost, 'some camera looked through where object 2 stands'
    assert all(crowded[c].visibility <= alone[c].visibility + 1e-9 for c in joints)
    # The occluder is where object 2 will be at object 1's instant, not where it was seen.
    (box,) = planner.occluders(mine)
    assert box.centre[1] == pytest.approx(0.01 + 0.04 * (2.0 - 2.5))
    assert planner.occluders(other)[0].centre[1] == pytest.approx(0.10)
