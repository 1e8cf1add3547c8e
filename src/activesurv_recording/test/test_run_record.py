"""The run record: one typed description of a run, written and read by the same class."""

from __future__ import annotations

import json
from pathlib import Path

import pydantic
import pytest

from activesurv_recording.bagio import open_writer
from activesurv_recording.errors import BagError
from activesurv_recording.run_record import (
    DemandRule,
    ExperimentRun,
    OnRig,
    RunRecord,
    SessionRun,
    StreamFacts,
    read_run_record,
)


def experiment() -> RunRecord:
    return RunRecord(
        run=ExperimentRun(set_name='A', demand_times=(1.0, 2.0), faults=('cam2@dead',)),
        system='fast',
        seed=3,
        initial_poses={'cam1': (0.1, 0.2)},
        obstacles=({'kind': 'box', 'centre': [0.1, 0.1, 0.0], 'size': [0.1, 0.1, 0.1]},),
    )


def session() -> RunRecord:
    return RunRecord(
        run=SessionRun(
            duration=60.0,
            stream=StreamFacts(
                seed=1,
                arrival_interval=8.0,
                first_entry=0.5,
                kinds=('line',),
                speed=0.025,
                acceleration=0.1,
            ),
            demands=DemandRule(mode='interval', interval=2.0),
        ),
        system='fast',
        seed=1,
    )


RIG = OnRig(hardware='/lab/hardware.yaml', name='lab', namespace='lab', time_origin=1.7e9)


def test_round_trip_and_frozen() -> None:
    for r in (experiment(), session(), experiment().with_hardware(RIG), session().as_replay()):
        back = RunRecord.from_json(r.to_json())
        assert back == r
        assert RunRecord.from_json(json.loads(r.to_json())) == r
    with pytest.raises(pydantic.ValidationError):
        experiment().seed = 4  # type: ignore[misc]


def test_kinds_modes_and_derived_facts() -> None:
    e, s = experiment(), session()
    assert (e.kind, e.mode, e.truth, e.time_origin) == ('experiment', 'graph', 'simulator', 0.0)
    assert (s.kind, s.mode) == ('session', 'surveil')
    h = e.with_hardware(RIG)
    assert (h.kind, h.mode, h.truth, h.time_origin) == ('hardware run', 'hardware', None, 1.7e9)
    assert s.with_hardware(RIG).kind == 'session'  # a session on a rig is a session
    r = e.as_replay()
    assert (r.kind, r.mode) == ('replay', 'replay')
    assert not e.offered_qos
    assert e.model_copy(update={'recorder': {'qos': 'offered'}}).offered_qos


LEGACY_GRAPH = {
    'rig': 'perturbed-1',
    'rig_source': 'nominal perturbed with seed 1',
    'rig_seed': 1,
    'calibration': '/cache/cal',
    'set': 'A',
    'system': 'fast',
    'seed': 1,
    'predictor': 'imm',
    'demand_times': [1.0, 2.0],
    'initial_poses': {'cam1': [0.1, 0.2]},
    'mode': 'graph',
    'marker_radius': 0.0125,
    'object': {'speed': 0.025},
    'faults': [],
    'setup': {'obstacles': [{'kind': 'box', 'centre': [0, 0, 0], 'size': [0.1, 0.1, 0.1]}]},
    'recorder': {'qos': 'offered'},
}


def test_legacy_bags_are_read() -> None:
    g = RunRecord.from_json(LEGACY_GRAPH)
    assert (g.kind, g.mode, g.rig.rig, g.offered_qos) == (
        'experiment',
        'graph',
        'perturbed-1',
        True,
    )
    assert isinstance(g.run, ExperimentRun)
    assert g.run.demand_times == (1.0, 2.0)
    assert len(g.obstacles) == 1  # from the believed set-up
    hw = {
        **LEGACY_GRAPH,
        'mode': 'hardware',
        'hardware': '/lab/hardware.yaml',
        'rig': 'lab',
        'namespace': 'lab',
        'time_origin': 1.7e9,
        'truth': 'table controller',
        'imagers': {'cam1': {'trigger': 'free'}},
    }
    h = RunRecord.from_json(hw)
    assert h.kind == 'hardware run'
    assert h.hardware is not None
    assert (h.hardware.name, h.truth, h.imagers) == ('lab', 'table controller', hw['imagers'])
    lock = RunRecord.from_json({**LEGACY_GRAPH, 'mode': 'lockstep'})
    assert lock.mode == 'lockstep'
    assert RunRecord.from_json({**LEGACY_GRAPH, 'mode': 'replay'}).kind == 'replay'
    s = RunRecord.from_json(
        {
            'mode': 'surveil',
            'system': 'fast',
            'seed': 1,
            'duration': 60.0,
            'stream': {
                'seed': 1,
                'arrival_interval': 8.0,
                'first_entry': 0.5,
                'kinds': ['line'],
                'at_once': 1,
                'speed': 0.025,
                'acceleration': 0.1,
            },
            'demands': {'mode': 'lines', 'interval': 2.0, 'lines_x': [0.25], 'region': [0, 1]},
            'initial_poses': {},
            'marker_radius': 0.0125,
            'obstacles': [],
        }
    )
    assert s.kind == 'session'
    assert isinstance(s.run, SessionRun)
    assert s.run.demands.mode == 'lines'


@pytest.mark.parametrize(
    'text',
    ['[1, 2]', 'not json', '{"mode": "graph"}', '{"record": 1, "run": {"kind": "x"}}'],
)
def test_what_is_no_run_record_is_refused_in_one_line(text: str) -> None:
    with pytest.raises(BagError, match='not an activesurv run record'):
        RunRecord.from_json(text)


def test_read_from_a_bag(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    w = open_writer(bag)
    w.write_json('/activesurv/run_info', 0, json.loads(session().to_json()))
    w.close()
    assert read_run_record(bag) == session()
    empty = tmp_path / 'empty'
    open_writer(empty).close()
    with pytest.raises(BagError, match='no /activesurv/run_info'):
        read_run_record(empty)
