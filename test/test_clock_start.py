"""Simulated time starts only when every process's /clock reader has matched the table's
writer (``graph.clock_readers``, ``xytable.start_shortfall``): a reader matched late left a
dispatcher at t = 0 for 8 simulated seconds at rtf 3, and seven demands without a camera."""

from __future__ import annotations

from pathlib import Path

import pytest

from activesurv_bringup.experiments.experiment import load_experiment
from activesurv_bringup.experiments.graph import clock_readers, graph_specs, group_processes
from activesurv_launch.launcher import NodeSpec
from activesurv_sim.xytable import start_shortfall

pytestmark = pytest.mark.cross


def test_the_table_waits_for_every_topic_it_names() -> None:
    wanted = {'object_state': 6, '/clock': 9}
    assert start_shortfall({'object_state': 6, '/clock': 9}, wanted) == ''
    assert start_shortfall({'object_state': 6, '/clock': 10}, wanted) == ''
    assert start_shortfall({'object_state': 6, '/clock': 8}, wanted) == '/clock 8 of 9'
    assert start_shortfall({}, wanted) == 'object_state 0 of 6, /clock 0 of 9'
    assert start_shortfall({}, {}) == ''


def test_one_clock_reader_per_simulated_time_process(tmp_path: Path) -> None:
    exp = load_experiment('A', 'fast', 1)
    specs = graph_specs(exp, tmp_path / 'bag', 1.0)
    nodes = specs[:-1]
    assert specs[-1].module == 'activesurv_sim.xy_table_node'
    # One process per node: every simulated-time node has its own reader.
    assert clock_readers(nodes) == sum(bool(s.parameters.get('use_sim_time')) for s in nodes)
    # Containers: one per process holding any simulated-time node (the members share it);
    # the paper's graph: four cameras, overhead, core, fusion and the recorder.
    grouped = group_processes(nodes)
    assert clock_readers(grouped) == 8
    assert clock_readers([NodeSpec('x', 'm', parameters={'use_sim_time': False})]) == 0


def test_a_cameras_driver_runs_with_its_imager_not_in_the_background() -> None:
    """A driver camera (``device:``) is grouped like a simulated one: in its camera's
    container at normal priority, not in the planners' ``core`` group at nice 5."""
    specs = [
        NodeSpec('cam1_camera', 'activesurv_hardware.camera_node'),
        NodeSpec('cam1_imager', 'activesurv_imaging.imager_node'),
        NodeSpec('predictor', 'activesurv_prediction.predictor_node'),
        NodeSpec('dispatcher', 'activesurv_dispatch.dispatcher_node'),
    ]
    grouped = {s.name: s for s in group_processes(specs)}
    assert sorted(grouped) == ['cam1', 'core']
    assert [m.name for m in grouped['cam1'].members] == ['cam1_camera', 'cam1_imager']
    assert grouped['cam1'].nice == 0


class _Graph:
    def raise_if_stopping(self) -> None:
        pass


class _Monitor:
    """Hears the nodes of ``then`` after ``after`` spins."""

    def __init__(self, then: set[str], after: int) -> None:
        self.ready: set[str] = set()
        self.spins = 0
        self._then, self._after = then, after

    def spin(self, seconds: float) -> None:
        self.spins += 1
        if self.spins >= self._after:
            self.ready |= self._then


def test_time_waits_for_the_fixes_matched_at_both_ends(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The locator (its writer has its two readers), the predictor (its reader has its
    publisher) and fusion (it hears the clock, requests and observations) must each say so
    before simulated time starts; a run once lost demand 0 to fixes published before the
    match, and another stamped its first estimate at time 0."""
    from activesurv_bringup.experiments import graph

    exp = load_experiment('A', 'fast', 1)
    grouped = group_processes(graph_specs(exp, tmp_path / 'bag', 1.0)[:-1])
    locator = [m for s in grouped for m in s.members if m.name == 'overhead_locator']
    assert locator[0].parameters['wait_for_readers'] == 2
    fusion = [m for s in grouped for m in (s.members or (s,)) if m.name == 'fusion']
    assert fusion[0].parameters['announce_ready'] is True
    said: list[str] = []
    both = {'overhead_locator', 'predictor', 'fusion'}
    monitor = _Monitor({'predictor'}, 3)
    monkeypatch.setattr(graph, 'READY_TIMEOUT', 0.3)
    graph._wait_until_matched(_Graph(), monitor, grouped, said.append)  # type: ignore[arg-type]
    assert said, 'no warning'
    assert said[0].startswith('warning: fusion, overhead_locator: inputs not matched'), said
    said.clear()
    monitor = _Monitor(both, 3)
    graph._wait_until_matched(_Graph(), monitor, grouped, said.append)  # type: ignore[arg-type]
    assert monitor.spins == 3
    assert monitor.ready == both
    assert not any(s.startswith('warning') for s in said), said
