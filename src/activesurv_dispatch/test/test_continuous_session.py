"""The dispatcher's session core in continuous surveillance: park between objects, withdraw the
demands of an object that left, forget the old ones (no ROS)."""

from __future__ import annotations

import numpy as np

from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.planner import Demand
from activesurv_dispatch.sensors import load_setup
from activesurv_dispatch.session import FORGET_AFTER, Dispatcher, DispatcherConfig

NORMAL = np.array([0.0, -1.0, 0.0])
COV = np.diag([4e-6, 4e-6, 2.5e-7, 1e-4, 1e-4, 1e-4])


def _demand(j: int, t: float, x: float, obj: int = 1) -> Demand:
    return Demand(j, t, np.array([x, 0.05, 0.05]), NORMAL, COV, obj)


def _session() -> tuple[Dispatcher, dict[str, np.ndarray]]:
    setup = load_setup(motion='fast')
    d = Dispatcher(setup, SensorModel.load(), DispatcherConfig())
    away = {c: q + 0.05 for c, q in setup.initial.items()}  # not where they wait
    for c, q in away.items():
        d.on_joints(c, q, 0.0)
    return d, away


def test_between_objects_the_cameras_go_back_to_their_initial_poses() -> None:
    d, _ = _session()
    out = d.set_horizon([], 0.0)
    parked = {g.camera_id: g.positions for g in out.goals}
    moving = [s.camera_id for s in d.setup.sensors if s.moves]
    assert sorted(parked) == sorted(moving)
    for c, q in parked.items():
        assert np.allclose(q, d.setup.initial[c])
    # Once sent, the same goals are not sent again on every replan.
    assert d.set_horizon([], 0.1).goals == []


def test_demands_of_an_object_that_left_are_withdrawn_not_failed() -> None:
    d, _ = _session()
    d.set_horizon([_demand(0, 2.0, 0.25), _demand(1, 4.0, 0.27)], 0.0)
    d.tick(0.5)
    out = d.set_horizon([], 0.6)  # the object left the table
    assert d.counts['withdrawn_demands'] == 2
    assert out.goals, 'and the cameras are parked'
    assert not d.tick(5.0).missed
    # An experiment's demands (object 0) are promised for good: they are reported missed.
    e, _ = _session()
    e.set_horizon([_demand(0, 2.0, 0.25, obj=0)], 0.0)
    e.set_horizon([], 0.6)
    assert [m.demand.index for m in e.tick(2.5).missed] == [0]


def test_a_long_session_forgets_demands_long_past() -> None:
    d, _ = _session()
    for j in range(5):
        d.set_horizon([_demand(j, 1.0 + j, 0.25)], 0.5 + j)
        d.tick(1.0 + j - 0.2)
        d.tick(1.0 + j + 0.01)
    assert len(d.demands) == 5
    d.tick(5.0 + FORGET_AFTER + 1.0)
    assert d.demands == {}
    assert d.scheduler.requested == {}


def test_every_stage_silent_at_once_is_a_stall_not_every_camera_dead() -> None:
    d, away = _session()
    # All four silent for 0.6 s (this node or its transport stalled): nobody is dropped ...
    out = d.tick(0.6)
    assert not d.down
    assert not [e for e in out.events if 'dispatching without it' in e[1]]
    # ... but one silent while the others speak is dropped, stall or not (once the others
    # had camera_timeout to be heard after the stall),
    for t in (1.0, 1.3, 1.55):
        for c, q in away.items():
            if c != 'cam2':
                d.on_joints(c, q, t)
        d.tick(t)
        assert set(d.down) == ({'cam2'} if t > 1.5 else set())
    # and a silence of all of them, however long, is a stall: nobody else is dropped.
    out = d.tick(2.6)
    assert set(d.down) == {'cam2'}
    assert [e for e in out.events if 'stalled' in e[1]]
    # When the stall ends, those not heard yet get camera_timeout to be heard ...
    d.on_joints('cam1', away['cam1'], 2.7)
    d.tick(2.75)
    assert set(d.down) == {'cam2'}
    # ... and one still silent after that is dropped.
    for t in (3.0, 3.3):
        for c in ('cam1', 'cam3'):
            d.on_joints(c, away[c], t)
    d.tick(3.3)
    assert set(d.down) == {'cam2', 'cam4'}


def test_a_stall_no_check_saw_ends_with_the_others_still_queued() -> None:
    """The process stalls between two checks (start-up): when it resumes, one camera's state
    comes before the check and the others' after it; none of them is dropped for it."""
    d, away = _session()
    d.tick(0.05)
    d.on_joints('cam2', away['cam2'], 0.6)  # the first message after a 0.55 s stall ...
    d.tick(0.6)  # ... then the check, before the others' queued states
    assert not d.down
    assert d.counts['stalls'] == 1
    for c, q in away.items():
        d.on_joints(c, q, 0.61)
    d.tick(0.65)
    assert not d.down
    # A camera still silent camera_timeout after the stall ended is dropped, as ever.
    for t in (0.9, 1.2):
        for c, q in away.items():
            if c != 'cam4':
                d.on_joints(c, q, t)
    d.tick(1.2)
    assert set(d.down) == {'cam4'}


def test_a_stage_stall_does_not_hide_an_imager_that_died() -> None:
    d, away = _session()
    for c in away:
        d.on_beat(c, 0.0)
    for t in (0.3, 0.55):  # every imager beats on but cam1's (killed at 0.1 s) ...
        for c in away:
            if c != 'cam1':
                d.on_beat(c, t)
    # ... while every stage state is 0.6 s old (the stages' process busy): a stall of the
    # stages, which drops none of them, but cam1's imager is silent alone: it is dropped.
    d.tick(0.6)
    assert set(d.down) == {'cam1'}
    assert 'heartbeat' in d.down['cam1']
    # Every imager silent at once is a stall of the imagers: nobody else is dropped.
    d2, away2 = _session()
    for c in away2:
        d2.on_beat(c, 0.0)
        d2.on_joints(c, away2[c], 0.55)
    d2.tick(0.6)
    assert not d2.down


def test_a_stage_fault_takes_its_camera_out_and_its_clearing_lets_it_back() -> None:
    d, away = _session()
    d.set_horizon([_demand(0, 2.0, 0.25), _demand(1, 4.0, 0.27)], 0.0)
    out = d.on_stage_fault('cam2', 'e-stop raised: goals refused; ready', 0.1)
    assert 'cam2' in d.planner.excluded
    assert d.down['cam2'] == 'stage fault: e-stop raised: goals refused; ready'
    assert any('cam2: stage fault' in text for _, text in out.events)
    assert d.on_stage_fault('cam2', 'e-stop raised: goals refused; ready', 0.2).events == []
    for c, q in away.items():  # heard all along: only the fault keeps it out
        d.on_joints(c, q, 0.3)
    d.tick(0.3)
    assert 'cam2' in d.planner.excluded
    out = d.on_stage_fault('cam2', '', 0.4)
    assert 'cam2' not in d.planner.excluded
    assert any('cam2 is back' in text for _, text in out.events)
    assert d.on_stage_fault('cam9', 'nothing of ours', 0.5).events == []  # unknown camera
