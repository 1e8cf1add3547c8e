"""Continuous surveillance: objects cross the table one after another, for as long as it runs.

``activesurv surveil`` runs the same node graph as an experiment, with three differences: the
xy table carries a stream of objects (:class:`activesurv_sim.stream.ObjectStream`), the
predictor gives each confirmed track an object id and its own demands (every
``demand_interval`` from its entry, or its predicted crossings of ``demand_at`` lines), and
the run ends at ``duration`` of simulated time or on SIGINT/SIGTERM. On the way out the
xy table stops first (no new demands), fusion answers every open demand, and the recorder
closes the bag; then ``results.json`` is written from the bag:
``{"mode": "surveil", "objects": [{"id", "entered", "left", "path_kind", ...}], "demands":
[... the experiment's keys + "object"]}``.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from activesurv_bringup.experiments.experiment import Experiment, load_experiment
from activesurv_bringup.experiments.graph import Progress, Until, graph_specs, run_graph
from activesurv_bringup.experiments.hardware_graph import (
    hardware_specs,
    place_cameras,
    start_margin,
)
from activesurv_bringup.experiments.options import RunOptions
from activesurv_bringup.experiments.session_options import (
    DEMAND_REGION,
    FIRST_ENTRY,
    SurveilOptions,
)
from activesurv_common.lifetime import StopRequested
from activesurv_evaluation.runs import finish_run
from activesurv_evaluation.session_report import write_surveil_report
from activesurv_hardware.hardware_file import Hardware
from activesurv_launch.launcher import NodeSpec
from activesurv_recording.run_record import DemandRule, RunRecord, SessionRun, StreamFacts


def surveil_record(exp: Experiment, s: SurveilOptions) -> RunRecord:
    """The session's run record (the stream is regenerated from it to evaluate the session)."""
    return RunRecord(
        run=SessionRun(
            set_name=s.set_name or None,
            duration=s.duration,
            stream=StreamFacts(
                seed=s.seed,
                arrival_interval=s.arrival_interval,
                first_entry=FIRST_ENTRY,
                kinds=tuple(s.path_kinds),
                at_once=int(s.objects_at_once),
                speed=exp.object_speed[0],
                acceleration=exp.object_speed[1],
                script=tuple(s.script),
            ),
            demands=DemandRule(
                mode='lines' if s.demand_at else 'interval',
                interval=s.demand_interval,
                lines_x=tuple(s.demand_at),
                region=tuple(DEMAND_REGION),
            ),
        ),
        **{**exp.record_facts(), 'system': s.system, 'seed': s.seed},
    )


def surveil_specs(
    exp: Experiment, bag: Path, s: SurveilOptions, opts: RunOptions
) -> list[NodeSpec]:
    """The experiment's node graph, turned continuous: streamed objects, per-object demands."""
    specs = graph_specs(
        exp,
        bag,
        opts.rtf,
        opts.image_rate,
        opts.faults,
        opts.thin,
        preview_rate=opts.preview_rate,
        record=surveil_record(exp, s),
    )
    return continuous(specs, exp, s, exp.overhead_rate)


def hardware_surveil_specs(
    exp: Experiment, hw: Hardware, bag: Path, s: SurveilOptions, opts: RunOptions, home: bool
) -> list[NodeSpec]:
    """A session on a real rig: the hardware graph, continuous, the table running the stream."""
    assert opts.time_origin is not None
    specs = hardware_specs(
        exp,
        hw,
        bag,
        opts.time_origin,
        opts.image_rate,
        home,
        True,
        opts.record_frames,
        record=surveil_record(exp, s),
    )
    # No demand phase on a rig: in the lab (30 Hz cameras, two 120 s sessions each) instants
    # half an overhead period off its frames were answered later, 140-145 ms against 125-127.
    return continuous(specs, exp, s, 0.0)


def demand_phase(interval: float, overhead_rate: float) -> float:
    """Half an overhead frame period (s), where it is shorter than the demand interval."""
    half = 0.5 / overhead_rate if overhead_rate > 0.0 else 0.0
    return half if half < interval else 0.0


TABLES = ('xy_table', 'table_runner')  # the simulated table, or the real table's runner


def continuous(
    specs: list[NodeSpec], exp: Experiment, s: SurveilOptions, overhead_rate: float
) -> list[NodeSpec]:
    """A run's node specs turned into a session's: bag retention, per-object demands, the
    table running the object stream, no fusion journal (the run record is the caller's).

    An object's interval demands come half an overhead frame period (``overhead_rate``, Hz;
    0: none) after its entry's grid: its entry is an overhead frame's stamp, and the instants
    fell on overhead frames (Set C: the last frame at its imager 6-32 ms after the instant,
    median latency 22.8 ms; see docs/performance.md)."""
    out = []
    for spec in specs:
        p = dict(spec.parameters)
        if spec.name == 'recorder':
            p.update(
                max_bag_duration=float(s.max_bag_duration),
                max_bag_size=float(s.max_bag_size),
                keep_bags=int(s.keep_bags),
            )
        elif spec.name == 'predictor':
            p.pop('demand_times', None)
            p.update(
                demand_mode='lines' if s.demand_at else 'interval',
                demand_interval=float(s.demand_interval),
                demand_phase=demand_phase(s.demand_interval, overhead_rate),
                demand_lines=[float(x) for x in s.demand_at] or [0.25],
                demand_region=[float(v) for v in DEMAND_REGION],
                objects_at_once=int(s.objects_at_once),
            )
        elif spec.name == 'overhead_locator' and s.objects_at_once > 1:
            p.update(all_markers=True)
        elif spec.name.endswith('_imager') and s.objects_at_once > 1:
            p.update(several_objects=True)
        elif spec.name in TABLES:
            p.update(
                path_type='stream',
                stream_seed=int(s.seed),
                arrival_interval=float(s.arrival_interval),
                path_kinds=list(s.path_kinds),
                start_time=FIRST_ENTRY,
            )
            if spec.name == 'xy_table':  # (a real table carries one object)
                p['objects_at_once'] = int(s.objects_at_once)
                if s.script:
                    p['stream_script'] = json.dumps(list(s.script))
            p.pop('path_points', None)
            p.pop('csv_file', None)
        elif spec.name == 'fusion':
            p.pop('journal', None)  # a session answers each demand once anyway
        out.append(replace(spec, parameters=p))
    return out


def run_surveil(
    out_dir: Path,
    s: SurveilOptions,
    options: RunOptions | None = None,
    progress: Progress = print,
    hardware: Hardware | None = None,
    home: bool = False,
) -> dict[str, Any]:
    """Run a continuous session into ``out_dir`` (bag, logs, results.json); returns results.

    With ``hardware`` the session runs on that rig, on the wall clock (the table, if it has
    one, runs the stream's objects one after another).

    Raises:
        ConfigError: for bad options.
        NodeDiedError: if a node dies.
    """
    opts = options or RunOptions()
    exp = load_experiment('A', s.system, s.seed, rig=s.rig)
    bag = out_dir / 'bag'
    before_start = None
    if hardware is None:
        specs = surveil_specs(exp, bag, s, opts)
    else:
        opts = replace(
            opts, time_origin=time.time(), namespace=hardware.namespace, processes='nodes', rtf=1.0
        )
        processes = len(hardware_surveil_specs(exp, hardware, bag, s, opts, home))
        origin = time.time() + start_margin(processes)
        opts = replace(opts, time_origin=origin)
        specs = hardware_surveil_specs(exp, hardware, bag, s, opts, home)
        before_start = place_cameras(exp, origin)
    limit = (s.duration or 7 * 24 * 3600.0) / max(opts.rtf, 1e-3) * 1.5 + 120.0
    last = [-1e9]

    def done(mon: Any) -> bool:
        return s.duration is not None and mon.sim_time >= s.duration

    def report(mon: Any) -> str | None:
        if mon.sim_time - last[0] < 10.0:
            return None
        last[0] = mon.sim_time
        ok = sum(1 for e in mon.estimates.values() if int(e.status) == 0)
        end = f' of {s.duration:.0f} s' if s.duration else ''
        return (
            f'{clock(mon)} time {mon.sim_time:.0f} s{end}: {len(mon.estimates)} demands '
            f'answered, {ok} ok'
        )

    try:
        run_graph(
            exp,
            out_dir,
            opts,
            progress,
            until=Until(done, limit, report),
            specs=specs,
            before_start=before_start,
        )
    except StopRequested as stop:
        # A session is open-ended: SIGINT, SIGTERM or SIGHUP is how it ends (the graph has
        # answered its open demands and closed the bag).
        if not (bag / 'metadata.yaml').is_file():
            raise
        signal_name = stop.signal_name
    else:
        signal_name = ''
    doc = finish_run(out_dir)
    if signal_name in ('SIGTERM', 'SIGHUP'):
        # A service manager's stop comes with a deadline (10 s): results.json is written, the
        # plots (seconds of matplotlib on a busy machine) are left to `activesurv report`.
        progress(f'report skipped (stopped by {signal_name}): activesurv report {out_dir}')
    else:
        progress(f'report: {write_surveil_report(doc, out_dir)}')
    return doc


def clock(monitor: Any) -> str:
    """What a session's progress calls its time: simulated, or a hardware run's wall time."""
    return 'run' if getattr(monitor, 'time_origin', None) is not None else 'simulated'
