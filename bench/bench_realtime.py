"""Real time: the node graph at rtf 1 on this machine (issue: real time and continuous operation).

* ``ok`` / ``ok_with_k``: Set A fast (seed 7) demands answered ``ok``, and with k cameras, at
  rtf 1 (``runs`` runs; the worst is reported).
* ``latency_ms`` / ``latency_p90_ms``: demand instant -> the TargetEstimate's publication
  (its ``published``, fusion's clock read between ``/clock`` ticks; at rtf 1 simulated seconds
  are wall seconds), median and 90th percentile over every demand of every run;
  ``latency_heard_ms``: the median of the same to when the recorder heard it (a listener at
  nice 10, one DDS hop and its own wake-up later).
* ``cpu_cores``: CPU seconds of every process of the run (nodes and orchestrator) over the wall
  seconds from the graph's start (before simulated time starts) to the recorder drained
  (median over runs); ``cpu_by_process`` itemises the first run. ``cpu_cores_running``: the
  same from 1 s of simulated time to the last demand (``cpu.json``'s ``running``): the rate a
  running graph keeps, without the start's discovery burst and the idle drain, whose share of
  a 10 s run changes ``cpu_cores`` by 0.05 from run to run. ``cpu_by_callback``: the first
  run's costliest callbacks (``ACTIVESURV_CALLBACK_CPU``: process, callback, calls, CPU
  seconds, ms a call; a callback's CPU includes what its container's members do with what it
  hands them in process), and ``cpu_in_callbacks`` the share of the nodes' CPU spent in
  callbacks at all (the rest: the executor and DDS). ``instant_occupancy``: the first run's
  median over its demands of the callbacks' CPU from the instant to the estimate over two
  cores x that time (:mod:`activesurv_evaluation.timeline`): near 1, the wait is the CPU.
* ``compute_ms``: the compute on each demand's critical path, median over the same demands:
  the slowest of its cameras' imaging of its frame (each observation carries its imager's
  ``compute_time``; the cameras image in parallel) plus fusion's processing (the estimate's
  ``compute_time``); ``latency_to_compute`` is ``latency_ms / compute_ms`` of the same runs
  (issue 35's goal: <= 1.5; p90 <= 2).
* ``compute_on_cores_ms``: the least time the same compute takes on this machine's cores
  (``cores``), where the k cameras' imaging shares them: per demand the slowest imaging or the
  sum of the k imagings over the cores, whichever is longer, plus fusion's; median.
  ``latency_to_compute_on_cores`` is ``latency_ms`` over it: the part of the latency that is
  not this host's compute, even with perfect scheduling and no hops.
* ``compute_unsplit_ms``: the same when each camera's imaging stays on one core, as it does
  (one thread of its camera's process): the best assignment of the k imagings to the cores,
  the busiest core's sum, plus fusion's; median. Three imagings on two cores: two of them one
  after the other. ``latency_to_compute_unsplit`` is ``latency_ms`` over it: the graph's own
  waits (hops, wake-ups, this VM's cold caches) beyond the compute as the processes can run it.
* ``max_rtf``: the highest of 1, 1.5, 2, 3, 4 at which all ten demands are still ``ok`` (in
  one of at most two runs at that rtf: a shared machine's stall of a fraction of a second
  costs several demands at rtf 4); ``max_rtf_runs`` lists every run's ``ok`` per rtf.
* ``*_nodes``: the same at rtf 1 with one process per node (``--processes nodes``).
* ``two_objects_*``: the same figures of Set C (two objects on the table at once and a post,
  a session of 15 demands; ``TWO_OBJECT_RUNS`` runs, seed 7, the rig told the truth),
  ``two_objects_latency_to_compute`` its ratio (issue 35: the same goal as one object).
* ``one_camera_*``: Set A fast at rtf 1 with k = 1 (one imaging camera per demand instead of
  three; ``runs`` runs): the graph's own waits when the imaging does not share two cores.
* ``camera_per_core_*``: the same with k = this host's cores (2 here, when fewer than three):
  each imaging camera has a core of its own, and what the latency holds beyond the compute is
  the graph's waits with every core busy (issue 35: the 1.5x goal asks this of k = 3 cameras).
* ``breakdown_ms``: where the latency goes, read off the first run's bag, medians over the
  demands, from the demand instant to: the table's state at the instant, the stage states at
  the instant (both as the recorder heard them, on the interpolated simulated clock), the
  first and the last assigned camera's frame reaching its imager (the observations'
  ``frame_received``), the last observation's and the estimate's publication (their
  ``published``), and the estimate as the recorder heard it (``estimate_heard``).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from activesurv_evaluation.timing import (
    compute_on_cores,
    compute_unsplit,
    critical_compute,
    published,
)

K = 3
RUNS = int(os.environ.get('ACTIVESURV_BENCH_RUNS', '3'))
TWO_OBJECT_RUNS = 2
CORES = len(os.sched_getaffinity(0))  # the cores this bench (and its graph) may use
ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def _run(
    rtf: float,
    tmp: Path,
    name: str,
    processes: str = 'containers',
    k: int | None = None,
    timed: bool = False,
) -> tuple[dict[str, Any], dict[str, Any]]:
    from activesurv_bringup.experiments.experiment import config_path, load_experiment
    from activesurv_bringup.experiments.graph import run_graph
    from activesurv_bringup.experiments.options import RunOptions, scoped_environ
    from activesurv_common.ros import callback_cpu
    from activesurv_evaluation.runs import load_run
    from activesurv_evaluation.timeline import write_timeline

    config = None
    if k is not None:  # the packaged experiments with another k
        doc = yaml.safe_load(Path(config_path()).read_text())
        doc['k'] = k
        config = tmp / f'experiments_k{k}.yaml'
        config.write_text(yaml.safe_dump(doc))
    exp = load_experiment('A', 'fast', 7, config_file=config)
    # The first run of a series also times each process's callbacks (cpu.json's callbacks).
    with scoped_environ({callback_cpu.ENV: '1'} if timed else {}):
        opts = RunOptions(rtf=rtf, processes=processes)
        run_graph(exp, tmp / name, opts, progress=lambda _: None)
    doc, cpu = load_run(tmp / name), json.loads((tmp / name / 'cpu.json').read_text())
    if timed and write_timeline(tmp / name, CORES, rtf, doc['demands']) is not None:
        cpu['timeline'] = json.loads((tmp / name / 'timeline.json').read_text())
    return doc, cpu


def _ok(doc: dict[str, Any]) -> tuple[int, int]:
    ok = [d for d in doc['demands'] if d['status'] == 'ok']
    return len(ok), sum(len(d['cameras']) >= K for d in ok)


def breakdown(bag: Path) -> dict[str, float]:
    """Median ms from each demand instant to each step of its capture (see module doc)."""
    from collections import defaultdict

    from activesurv_recording.bagio import read_bag

    def stamp(h: Any) -> float:
        return float(h.stamp.sec) + 1e-9 * float(h.stamp.nanosec)

    instants: dict[float, list[str]] = {}
    steps: dict[float, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for m in read_bag(bag):
        t = m.t_ns * 1e-9
        if m.topic == '/capture_request':
            tj = round(float(m.msg.demand_instant.sec) + 1e-9 * m.msg.demand_instant.nanosec, 4)
            instants[tj] = [str(c) for c in m.msg.camera_ids]
            continue
        if not hasattr(m.msg, 'header'):
            continue
        tj = round(stamp(m.msg.header), 4)
        if tj not in instants:
            continue
        if m.topic == '/object_state':
            steps[tj]['state'].append(t)
        elif m.topic.endswith('/stage/joint_states'):
            if m.topic.split('/')[1] in instants[tj]:
                steps[tj]['stages'].append(t)
        elif m.topic.endswith('/image_raw') and m.topic.split('/')[1] in instants[tj]:
            steps[tj]['frames'].append(t)
        elif m.topic == '/marker_observations':
            # The imager's own clock where the observation says it (frame, publication).
            if (got := published(m.msg, 'frame_received')) is not None:
                steps[tj]['frames_told'].append(tj + got)
            told = published(m.msg)
            steps[tj]['observations'].append(tj + told if told is not None else t)
        elif m.topic == '/target_estimate':
            told = published(m.msg)
            steps[tj]['estimate'].append(tj + told if told is not None else t)
            steps[tj]['heard'].append(t)
    rows: dict[str, list[float]] = defaultdict(list)
    for tj, s in steps.items():
        if s.get('frames_told'):
            s['frames'] = s['frames_told']
        for key, pick, name in (
            ('state', min, 'table_state'),
            ('stages', max, 'stage_states'),
            ('frames', min, 'first_frame'),
            ('frames', max, 'last_frame'),
            ('observations', max, 'last_observation'),
            ('estimate', min, 'estimate'),
            ('heard', min, 'estimate_heard'),
        ):
            if s.get(key):
                rows[name].append(1e3 * (pick(s[key]) - tj))
    order = (
        'table_state',
        'stage_states',
        'first_frame',
        'last_frame',
        'last_observation',
        'estimate',
        'estimate_heard',
    )
    return {k: round(statistics.median(rows[k]), 1) for k in order if rows.get(k)}


def _set_c(tmp: Path, name: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """One Set C run (two objects at once and a post) at rtf 1: results and cpu.json."""
    out = tmp / name
    subprocess.run(
        [ACTIVESURV, 'experiment', '--set', 'C', '--system', 'fast', '--seed', '7']
        + ['--calibration', 'truth', '--out', str(out)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        timeout=900,
    )
    doc = json.loads((out / 'results.json').read_text())
    return doc, json.loads((out / 'cpu.json').read_text())


def _series(
    tmp: Path, processes: str, runs: int, k: int | None = None, two_objects: bool = False
) -> dict[str, Any]:
    oks, lat, heard, cores, first_cpu, compute = [], [], [], [], None, []
    by_callback, in_callbacks, occupancy = None, None, None
    running: list[float] = []
    shared: list[float] = []
    unsplit: list[float] = []
    n = 0
    for r in range(runs):
        name = f'{processes}{r}' + (f'_k{k}' if k else '') + ('_C' if two_objects else '')
        timed = r == 0 and not two_objects  # the first run itemises its callbacks too
        doc, cpu = _set_c(tmp, name) if two_objects else _run(1.0, tmp, name, processes, k, timed)
        n = len(doc['demands'])
        oks.append(_ok(doc))
        lat += [d['latency'] for d in doc['demands'] if d['latency'] is not None]
        heard += [
            h
            for d in doc['demands']
            if (h := (d.get('timing') or {}).get('heard', {}).get('estimate')) is not None
        ]
        compute += [
            c for d in doc['demands'] if (c := critical_compute(d.get('timing') or {})) is not None
        ]
        shared += [
            c
            for d in doc['demands']
            if (c := compute_on_cores(d.get('timing') or {}, CORES)) is not None
        ]
        unsplit += [
            c
            for d in doc['demands']
            if (c := compute_unsplit(d.get('timing') or {}, CORES)) is not None
        ]
        cores.append(cpu['cores'])
        if 'running' in cpu:
            running.append(cpu['running']['cores'])
        if first_cpu is None:
            first_cpu = cpu['cpu_seconds']
            by_callback = cpu.get('top_callbacks')
            in_callbacks = _in_callbacks(cpu)
            occupancy = (cpu.get('timeline') or {}).get('median_occupancy')
    return {
        'ok': f'{min(o for o, _ in oks)}/{n}',
        'ok_with_k': f'{min(k for _, k in oks)}/{n}',
        'latency_ms': round(1e3 * statistics.median(lat), 1) if lat else None,
        'latency_p90_ms': round(1e3 * float(np.percentile(lat, 90)), 1) if lat else None,
        'latency_heard_ms': round(1e3 * statistics.median(heard), 1) if heard else None,
        'compute_ms': round(1e3 * statistics.median(compute), 2) if compute else None,
        'latency_to_compute': round(statistics.median(lat) / statistics.median(compute), 2)
        if lat and compute
        else None,
        'latency_p90_to_compute': round(
            float(np.percentile(lat, 90)) / statistics.median(compute), 2
        )
        if lat and compute
        else None,
        'compute_on_cores_ms': round(1e3 * statistics.median(shared), 2) if shared else None,
        'latency_to_compute_on_cores': round(statistics.median(lat) / statistics.median(shared), 2)
        if lat and shared
        else None,
        'compute_unsplit_ms': round(1e3 * statistics.median(unsplit), 2) if unsplit else None,
        'latency_to_compute_unsplit': round(statistics.median(lat) / statistics.median(unsplit), 2)
        if lat and unsplit
        else None,
        'cpu_cores': round(statistics.median(cores), 3),
        'cpu_cores_running': round(statistics.median(running), 3) if running else None,
        'cpu_by_process': first_cpu,
        'cpu_by_callback': by_callback,
        'cpu_in_callbacks': in_callbacks,
        'instant_occupancy': occupancy,
        'all_ok': all(o == n for o, _ in oks),
    }


def _in_callbacks(cpu: dict[str, Any]) -> float | None:
    """The share of the run's node CPU (``cpu_seconds``, the orchestrator left out) spent in
    the nodes' callbacks (``ACTIVESURV_CALLBACK_CPU``); the rest is the executor's and DDS's."""
    calls = cpu.get('callbacks')
    nodes = sum(v for k, v in cpu['cpu_seconds'].items() if k != 'orchestrator')
    if not calls or nodes <= 0.0:
        return None
    spent = sum(s for doc in calls.values() for _, s in doc['callbacks'].values())
    return round(spent / nodes, 3)


def run() -> dict[str, object]:
    out: dict[str, object] = {'load_average_1min': round(os.getloadavg()[0], 2), 'runs': RUNS}
    out['cores'] = CORES
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        main = _series(tmp, 'containers', RUNS)
        out['breakdown_ms'] = breakdown(tmp / 'containers0' / 'bag')
        all_ok = main.pop('all_ok')
        out.update(main)
        nodes = _series(tmp, 'nodes', 1)
        nodes.pop('all_ok')
        for k in ('ok', 'latency_ms', 'latency_p90_ms', 'cpu_cores'):
            out[f'{k}_nodes'] = nodes[k]
        shown = ('ok', 'latency_ms', 'latency_p90_ms', 'compute_ms', 'latency_to_compute')
        shown += ('compute_on_cores_ms', 'latency_to_compute_on_cores')
        shown += ('compute_unsplit_ms', 'latency_to_compute_unsplit')
        two = _series(tmp, 'containers', TWO_OBJECT_RUNS, two_objects=True)
        for k in (*shown, 'latency_p90_to_compute', 'cpu_cores', 'cpu_cores_running'):
            out[f'two_objects_{k}'] = two[k]
        one = _series(tmp, 'containers', RUNS, k=1)
        for k in (*shown, 'instant_occupancy'):
            out[f'one_camera_{k}'] = one[k]
        if 1 < CORES < K:  # as many imaging cameras as cores: each has one of its own
            own = _series(tmp, 'containers', RUNS, k=CORES)
            out['camera_per_core_k'] = CORES
            for k in (*shown, 'latency_p90_to_compute'):
                out[f'camera_per_core_{k}'] = own[k]
        best = 1.0 if all_ok else 0.0
        attempts: dict[str, list[str]] = {}
        if best:
            for rtf in (1.5, 2.0, 3.0, 4.0):
                # A second run where the first lost a demand: on this shared machine one stall
                # of 0.7 s (every stage state silent at once, the dispatcher says) costs three
                # demands at rtf 4; the graph keeps up if either run serves all ten.
                for attempt in range(2):
                    d, _ = _run(rtf, tmp, f'rtf{rtf:g}_{attempt}')
                    ok = _ok(d)[0]
                    attempts.setdefault(f'{rtf:g}', []).append(f'{ok}/{len(d["demands"])}')
                    if ok == len(d['demands']):
                        break
                if ok < len(d['demands']):
                    break
                best = rtf
        out['max_rtf'] = best
        out['max_rtf_runs'] = attempts
    return out
