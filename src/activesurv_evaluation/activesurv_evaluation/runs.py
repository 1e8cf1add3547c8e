"""A run's results: evaluated from its bag and run record, written once by :func:`finish_run`.

From a bag alone (the orchestrator stores the run's record in it):

* truth: ``object_state`` (the xy table's side marker and normal), interpolated to each demand
  instant;
* assignment: the ``capture_request`` of each demand;
* visibility (eq. 2): from the ``marker_observations`` that succeeded, with each camera's pose at
  the exposure, for the true target;
* estimate, faulty cameras, status: the ``target_estimate`` of each demand; its latency is its
  bag time minus the demand instant.

Every route that runs something (a graph, network namespaces, lockstep, a session, a hardware
run) ends in :func:`finish_run`, which writes ``results.json``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_common.sensor_model import SensorModel
from activesurv_common.timeseries import TimeSeries
from activesurv_evaluation.records import (
    DEMAND_TOPICS,
    TRUTH_TOLERANCE,
    DemandMessages,
    demand_record,
    msg_stamp,
    msg_vector,
    run_obstacles,
)
from activesurv_evaluation.results import (
    DemandRecord,
    PredictionLog,
    results_document,
    write_results,
)
from activesurv_evaluation.session import evaluate_surveil
from activesurv_evaluation.timing import StepTimes, published, step_topics
from activesurv_evaluation.tracking import TrackRecorder
from activesurv_hardware.stage_faults import StageFaults
from activesurv_recording.bagio import read_bag
from activesurv_recording.errors import BagError
from activesurv_recording.run_record import ExperimentRun, RunRecord, read_run_record

TOPICS = DEMAND_TOPICS | {'/diagnostics'}  # an experiment's: its stage faults too


def demand_truth(
    truth: TimeSeries, t: float, ended: bool, heard_of: bool
) -> np.ndarray[Any, np.dtype[np.float64]] | None:
    """The true state (side marker, normal) a demand at ``t`` is evaluated against: the table's
    own state of the instant, or the states around it interpolated. NaN where there is none
    (a gap in the table's reports; an instant after its last state, as when a stop ended the
    table first: its last state held would be a stale truth, 1 mm off for an object at 20 mm/s
    50 ms on), so the demand is kept without errors. None when the run ended (``ended``)
    before the demand and nothing of it was heard (``heard_of``): the demands so far."""
    s = truth.at(t, hold=TRUTH_TOLERANCE)
    if s is not None:
        return s
    return None if ended and not heard_of else np.full(6, np.nan)


def experiment_facts(record: RunRecord) -> dict[str, Any]:
    """The keys an experiment's ``results.json`` carries about the run (every route alike)."""
    run = record.run
    assert isinstance(run, ExperimentRun)
    return {
        'seed': record.seed,
        'mode': record.mode,
        'predictor': record.predictor,
        'faults': list(run.faults),
        # The simulated hardware and what the system was told (None: round-1 runs); on a
        # real rig, its name.
        **record.rig.model_dump(),
        **({'rig': record.hardware.name} if record.hardware is not None else {}),
        # Where the truth comes from: the simulator, or a real table's controller.
        'truth': record.truth,
        **({'hardware': record.hardware.hardware} if record.hardware is not None else {}),
    }


class _RunBag(DemandMessages):
    """What an experiment's bag says, gathered message by message."""

    def __init__(self, origin: float) -> None:
        super().__init__()
        self.origin = origin
        self.truth = TimeSeries(6, capacity=10**7)
        self.steps = StepTimes()
        self.predicted = PredictionLog()
        self.tracked = TrackRecorder()
        self.faults = StageFaults()

    def hear(self, m: Any) -> None:
        if self.steps.hear(m.topic, m.msg, m.t_ns * 1e-9) or self.hear_demand(m):
            return
        if m.topic == '/demand_horizon':
            made = msg_stamp(m.msg)
            for d in m.msg.demands:
                p = d.pose.pose.position
                self.predicted.add(made, int(d.index), (p.x, p.y, p.z), d.pose.covariance)
        elif m.topic == '/object_state':
            self.truth.add(
                msg_stamp(m.msg),
                np.r_[msg_vector(m.msg.side_marker), msg_vector(m.msg.side_normal)],
            )
            self.tracked.on_truth(msg_stamp(m.msg), m.msg)
        elif m.topic == '/object_tracks':
            self.tracked.on_tracks(msg_stamp(m.msg), m.msg)
        elif m.topic == '/diagnostics':
            self.faults.hear(msg_stamp(m.msg) - self.origin, m.msg)


def evaluate_bag(bag: Path, partial: bool = False) -> dict[str, Any]:
    """The results document of one recorded experiment (``partial``: stopped early by a
    signal, so the demands its truth covers).

    Raises:
        BagError: for a missing, damaged or foreign bag.
    """
    record = read_run_record(bag)
    run = record.run
    if not isinstance(run, ExperimentRun):
        raise BagError(f'bag {bag} is a {record.kind}, not an experiment')
    # A hardware run: its demand instants are wall clock, run time 0 at ``time_origin``.
    origin = record.time_origin
    truthless = record.truth is None
    heard = _RunBag(origin)
    for m in read_bag(bag, TOPICS | step_topics(record.initial_poses)):
        heard.hear(m)
    if len(heard.truth) == 0 and not truthless and not partial:
        raise BagError(f'bag {bag} has no object_state: no ground truth to evaluate against')
    records = _demand_records(heard, record, run.demand_times, truthless, partial)
    times = run.demand_times
    doc = results_document(
        run.set_name,
        record.system,
        records,
        {
            **experiment_facts(record),
            # A stage controller's faults (stall, controller lost, e-stop) and when they cleared.
            **({'stage_faults': heard.faults.events} if heard.faults.events else {}),
            # A run stopped by a signal: how many demands it was to answer.
            **({'demands_planned': len(times)} if len(records) < len(times) else {}),
        },
        heard.tracked.metrics() if not truthless else None,
    )
    if truthless:  # nothing measured the object: no truth columns at all
        for row in doc['demands']:
            for key in ('true_position', 'true_normal', 'position_error', 'orientation_error'):
                row.pop(key, None)
    return doc


def _demand_records(
    heard: _RunBag,
    record: RunRecord,
    times: Sequence[float],
    truthless: bool,
    partial: bool,
) -> list[DemandRecord]:
    model = SensorModel.load()
    obstacles = run_obstacles(record)
    records = []
    last_truth = heard.truth.latest_time
    for j, t_run in enumerate(times):
        tj = heard.origin + t_run
        ended = partial or (last_truth is not None and tj > last_truth + 0.5)
        heard_of = j in heard.requests or j in heard.estimates
        s = demand_truth(heard.truth, tj, ended, heard_of) if not truthless else np.full(6, np.nan)
        if s is None:
            break  # the run was stopped (a signal) before this instant: the demands so far
        observed = heard.observations.get(j, [])
        est = heard.estimates.get(j)
        rec = demand_record(
            j,
            tj,
            s,
            heard.requests.get(j),
            [o for o, _ in observed],
            est,
            model,
            obstacles,
            record.marker_radius,
        )
        rec.timing = heard.steps.timing(
            tj,
            rec.assigned,
            observed,
            None if est is None else est[1] * 1e-9,
            None if est is None else published(est[0]),
            None if est is None else published(est[0], 'compute_time'),
        )
        rec.t = t_run
        rec.predictions = heard.predicted.picks(j, tj)
        records.append(rec)
    return records


def run_bag(run: Path) -> Path:
    """The bag of a run directory (or ``run`` itself if it is a bag)."""
    return run if (run / 'metadata.yaml').is_file() else run / 'bag'


def evaluate_run(bag: Path, partial: bool = False) -> dict[str, Any]:
    """The results document of a recorded run of any kind."""
    if isinstance(read_run_record(bag).run, ExperimentRun):
        return evaluate_bag(bag, partial)
    return evaluate_surveil(bag)


def find_runs(path: Path) -> list[Path]:
    """Run directories under ``path`` (a run has ``bag/`` or ``results.json``), or ``path``."""
    if (
        (path / 'bag').is_dir()
        or (path / 'results.json').is_file()
        or (path / 'metadata.yaml').is_file()
    ):
        return [path]
    return sorted(
        p
        for p in path.iterdir()
        if p.is_dir() and ((p / 'bag').is_dir() or (p / 'results.json').is_file())
    )


def load_run(
    run: Path, refresh: bool = True, write: bool = True, partial: bool = False
) -> dict[str, Any]:
    """The results of a run: from its bag (writing results.json unless ``write`` is False) or,
    without ``refresh`` and with a results.json, from that. ``partial``: the run was stopped
    early (a signal); the demands whose instant its truth covers, none if it has none."""
    bag = run_bag(run)
    have = (run / 'results.json').is_file()
    if bag.is_dir() and (refresh or not have):
        doc = evaluate_run(bag, partial)
        if write:
            out = run.parent if bag == run else run
            write_results(out / 'results.json', doc)
        return doc
    try:
        return dict(json.loads((run / 'results.json').read_text()))
    except (OSError, ValueError) as exc:
        raise BagError(f'{run}: neither a bag nor a readable results.json') from exc


def finish_run(
    out: Path,
    *,
    partial: bool = False,
    record: RunRecord | None = None,
    demands: Sequence[DemandRecord] | None = None,
    tracking: dict[str, Any] | None = None,
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Write ``out/results.json`` for a finished (or, ``partial``, a stopped) run; returns it.

    A run with a bag (``out/bag``) is evaluated from the bag and the record in it; a lockstep
    run (no bag) gives its ``record`` and ``demands`` (and the overhead ``tracking``). ``extra``
    keys are added (a netns run's host traffic).

    Raises:
        BagError: for a run with neither a bag nor demands, or a damaged bag.
    """
    if demands is not None:
        if record is None:
            raise BagError('finish_run: demands without their run record')
        run = record.run
        assert isinstance(run, ExperimentRun)
        doc = results_document(
            run.set_name, record.system, demands, experiment_facts(record), tracking
        )
    elif (out / 'bag' / 'metadata.yaml').is_file():
        doc = evaluate_run(out / 'bag', partial)
    else:
        raise BagError(f'{out}: no bag to evaluate (was the run stopped before it began?)')
    if extra:
        doc.update(extra)
    write_results(out / 'results.json', doc)
    return doc
