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
import statistics
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_bringup.errors import BagError
from activesurv_bringup.experiments.experiment import Experiment, load_experiment
from activesurv_bringup.experiments.graph import Progress, Until, graph_specs, run_graph
from activesurv_bringup.experiments.hardware_graph import (
    START_MARGIN,
    hardware_specs,
    place_cameras,
)
from activesurv_bringup.experiments.options import RunOptions
from activesurv_bringup.experiments.records import (
    demand_record,
    msg_stamp,
    msg_vector,
    run_obstacles,
)
from activesurv_bringup.experiments.session_options import (
    DEMAND_REGION,
    FIRST_ENTRY,
    SurveilOptions,
)
from activesurv_common.lifetime import StopRequested
from activesurv_common.occlusion import obstacles_to_list, plate_box
from activesurv_common.sensor_model import SensorModel
from activesurv_common.timeseries import TimeSeries
from activesurv_hardware.hardware_file import Hardware
from activesurv_launch.launcher import NodeSpec
from activesurv_recording.bagio import read_bag, run_info
from activesurv_sim.stream import ObjectStream
from activesurv_studies.tracking import TrackRecorder, track_metrics


def surveil_info(exp: Experiment, s: SurveilOptions) -> dict[str, Any]:
    """What the bag stores about the session (the stream is regenerated from it)."""
    return {
        'mode': 'surveil',
        'system': s.system,
        'seed': s.seed,
        'duration': s.duration,
        'stream': {
            'seed': s.seed,
            'arrival_interval': s.arrival_interval,
            'first_entry': FIRST_ENTRY,
            'kinds': list(s.path_kinds),
            'at_once': int(s.objects_at_once),
            'speed': exp.object_speed[0],
            'acceleration': exp.object_speed[1],
            **({'script': list(s.script)} if s.script else {}),
        },
        **({'set': s.set_name} if s.set_name else {}),
        'demands': {
            'mode': 'lines' if s.demand_at else 'interval',
            'interval': s.demand_interval,
            'lines_x': list(s.demand_at),
            'region': list(DEMAND_REGION),
        },
        'initial_poses': {c: [float(v) for v in q] for c, q in exp.setup.initial.items()},
        'marker_radius': exp.setup.marker_radius,
        'obstacles': obstacles_to_list(exp.setup.obstacles),
    }


def surveil_specs(
    exp: Experiment, bag: Path, s: SurveilOptions, opts: RunOptions
) -> list[NodeSpec]:
    """The experiment's node graph, turned continuous: streamed objects, per-object demands."""
    specs = graph_specs(
        exp, bag, opts.rtf, opts.image_rate, opts.faults, opts.thin, preview_rate=opts.preview_rate
    )
    return continuous(specs, exp, s)


def hardware_surveil_specs(
    exp: Experiment, hw: Hardware, bag: Path, s: SurveilOptions, opts: RunOptions, home: bool
) -> list[NodeSpec]:
    """A session on a real rig: the hardware graph, continuous, the table running the stream."""
    assert opts.time_origin is not None
    specs = hardware_specs(
        exp, hw, bag, opts.time_origin, opts.image_rate, home, True, opts.record_frames
    )
    return continuous(specs, exp, s)


# What a hardware run's recorder stores beside the session's description.
HARDWARE_INFO = ('hardware', 'rig', 'namespace', 'time_origin', 'truth', 'setup')
TABLES = ('xy_table', 'table_runner')  # the simulated table, or the real table's runner


def continuous(specs: list[NodeSpec], exp: Experiment, s: SurveilOptions) -> list[NodeSpec]:
    """A run's node specs turned into a session's: the session's run description and bag
    retention, per-object demands, the table running the object stream, no fusion journal."""
    info = surveil_info(exp, s)
    out = []
    for spec in specs:
        p = dict(spec.parameters)
        if spec.name == 'recorder':
            old = json.loads(p['run_info'])
            if old.get('mode') == 'hardware':
                info.update({k: old[k] for k in HARDWARE_INFO if k in old})
            p.update(
                run_info=json.dumps(info),
                max_bag_duration=float(s.max_bag_duration),
                max_bag_size=float(s.max_bag_size),
                keep_bags=int(s.keep_bags),
            )
        elif spec.name == 'predictor':
            p.pop('demand_times', None)
            p.update(
                demand_mode='lines' if s.demand_at else 'interval',
                demand_interval=float(s.demand_interval),
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
        origin = time.time() + START_MARGIN
        opts = replace(
            opts, time_origin=origin, namespace=hardware.namespace, processes='nodes', rtf=1.0
        )
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
    except StopRequested:
        # A session is open-ended: SIGINT, SIGTERM or SIGHUP is how it ends (the graph has
        # answered its open demands and closed the bag).
        if not (bag / 'metadata.yaml').is_file():
            raise
    doc = evaluate_surveil(bag)
    (out_dir / 'results.json').write_text(json.dumps(doc, indent=2) + '\n')
    progress(f'report: {write_surveil_report(doc, out_dir)}')
    return doc


def clock(monitor: Any) -> str:
    """What a session's progress calls its time: simulated, or a hardware run's wall time."""
    return 'run' if getattr(monitor, 'time_origin', None) is not None else 'simulated'


def evaluate_surveil(bag: Path) -> dict[str, Any]:
    """The results document of a continuous session, from its bag (split or not).

    Every demand that got a capture request (a promise to the user) has a record; demands
    withdrawn before their request (the object left first) have none.

    Raises:
        BagError: for a missing, damaged or foreign bag.
    """
    info = run_info(bag)
    if info.get('mode') != 'surveil':
        raise BagError(f'bag {bag} is not a surveil session (mode {info.get("mode")!r})')
    origin = float(info.get('time_origin') or 0.0)  # a hardware session: wall clock
    st = info['stream']
    stream = ObjectStream(
        int(st['seed']),
        float(st['arrival_interval']),
        float(st['first_entry']),
        list(st['kinds']),
        speed=float(st['speed']),
        acceleration=float(st['acceleration']),
        at_once=int(st.get('at_once', 1)),
        script=st.get('script', ()),
    )

    def truth_id(t: float) -> int:
        p = stream.pass_at(t - origin)
        return 0 if p is None else int(p.id)

    # One truth per lane (several objects at once publish a state per lane and tick).
    truths: dict[int, TimeSeries] = {}
    presents: dict[int, TimeSeries] = {}
    requests: dict[int, Any] = {}
    observations: dict[int, list[Any]] = {}
    estimates: dict[int, tuple[Any, int]] = {}
    object_of: dict[int, int] = {}
    confirmed: dict[int, float] = {}
    end = 0.0
    tracked = TrackRecorder(truth_id)
    topics = {
        '/object_state',
        '/object_tracks',
        '/capture_request',
        '/marker_observations',
        '/target_estimate',
        '/demand_horizon',
    }
    for m in read_bag(bag, topics):
        end = max(end, m.t_ns * 1e-9)
        if m.topic == '/object_state':
            t = msg_stamp(m.msg)
            slot = int(getattr(m.msg, 'slot', 0))
            if slot not in truths:
                truths[slot] = TimeSeries(6, capacity=10**7)
                presents[slot] = TimeSeries(1, capacity=10**7)
            truths[slot].add(
                t, np.r_[msg_vector(m.msg.side_marker), msg_vector(m.msg.side_normal)]
            )
            presents[slot].add(t, [1.0 if m.msg.in_workspace else 0.0])
            tracked.on_truth(t, m.msg)
        elif m.topic == '/object_tracks':
            tracked.on_tracks(msg_stamp(m.msg), m.msg)
        elif m.topic == '/demand_horizon':
            for d in m.msg.demands:
                oid = int(d.object_id)
                object_of[int(d.index)] = oid
                confirmed.setdefault(oid, msg_stamp(m.msg))
        elif m.topic == '/capture_request':
            requests.setdefault(int(m.msg.demand_index), m.msg)
        elif m.topic == '/marker_observations':
            observations.setdefault(int(m.msg.demand_index), []).append(m.msg)
        elif m.topic == '/target_estimate':
            estimates.setdefault(int(m.msg.demand_index), (m.msg, m.t_ns))
    model = SensorModel.load()
    obstacles = run_obstacles(info)
    radius = float(info.get('marker_radius', 0.0125))
    demands = []
    for j in sorted(set(requests) | set(estimates)):
        req = requests.get(j)
        tj = (
            float(req.demand_instant.sec) + 1e-9 * float(req.demand_instant.nanosec)
            if req is not None
            else msg_stamp(estimates[j][0])
        )
        here = _objects_at(truths, presents, tj)
        if not here:
            parked = truths[0].at(tj, hold=0.5) if 0 in truths else None
            if parked is None:
                continue
            here = [parked]
        guess = (
            msg_vector(req.predicted_position)
            if req is not None
            else msg_vector(estimates[j][0].position)
        )
        s = min(here, key=lambda v: float(np.linalg.norm(v[:3] - guess)))
        blocking = None
        if obstacles is not None:  # the other objects' plates stand in the way too
            blocking = list(obstacles) + [
                plate_box(o[:3], o[3:], OBJECT_HALF_SIZE) for o in here if o is not s
            ]
        rec = demand_record(
            j, tj, s, req, observations.get(j, []), estimates.get(j), model, blocking, radius
        )
        doc = rec.to_json()
        doc['t'] = tj - origin
        doc['object'] = object_of.get(j, 0)
        demands.append(doc)
    objects = []
    for oid, t in sorted(confirmed.items()):
        if oid == 0:
            continue
        p = _pass_of(stream, tracked, oid, t - origin, origin)
        objects.append(
            {
                'id': oid,
                'entered': None if p is None else p.entered,
                'left': None if p is None or p.left > end - origin else p.left,
                'path_kind': None if p is None else p.kind,
                'truth_id': None if p is None else p.id,
                'confirmed': t - origin,
                'demands': sum(1 for d in demands if d['object'] == oid),
            }
        )
    lat = [d['latency'] for d in demands if d.get('latency') is not None]
    tracking = (
        tracked.metrics() if 'hardware' not in info or info.get('truth') else track_metrics([], [])
    )
    return {
        'mode': 'surveil',
        **({'set': info['set']} if info.get('set') else {}),
        'system': info.get('system'),
        'seed': info.get('seed'),
        'demand_mode': info['demands']['mode'],
        'simulated_seconds': end - origin,
        **(
            {'hardware': info['hardware'], 'truth': info.get('truth')}
            if 'hardware' in info
            else {}
        ),
        'objects': objects,
        'obstacles': obstacles_to_list(obstacles or ()),
        'demands': demands,
        'summary': {
            'demands': len(demands),
            'ok': sum(1 for d in demands if d['status'] == 'ok'),
            'objects': len(objects),
            'latency_median_ms': 1e3 * statistics.median(lat) if lat else None,
            **tracking,
        },
    }


OBJECT_HALF_SIZE = 0.03  # m: half side of an object's marker plates (ObjectGeometry)


def _pass_of(
    stream: ObjectStream, tracked: TrackRecorder, oid: int, t: float, origin: float
) -> Any:
    """The stream's object that track ``oid`` followed, confirmed at run time ``t``: the one
    on the table then (several at once: the one nearest the track's first estimate)."""
    passes = stream.passes_at(t)
    if len(passes) <= 1:
        return passes[0] if passes else stream.pass_at(t)
    for stamp, items in sorted(tracked.tracks):
        for i, x, y in items:
            if i == oid:
                xy = np.array([x, y])
                return min(
                    passes,
                    key=lambda p: float(
                        np.linalg.norm(p.path.position(stamp - origin - p.entered) - xy)
                    ),
                )
    return passes[0]


def _objects_at(
    truths: dict[int, TimeSeries], presents: dict[int, TimeSeries], t: float
) -> list[np.ndarray]:
    """Side marker and normal (6,) of every object on the table at ``t``."""
    out = []
    for slot, series in truths.items():
        here = presents[slot].at(t, hold=0.5)
        s = series.at(t, hold=0.5)
        if s is not None and here is not None and here[0] > 0.5:
            out.append(s)
    return out


def session_table(doc: dict[str, Any]) -> str:
    """One line per object: path kind, entry/exit, demands, ok, median errors and latency."""
    head = (
        f'{"object":>6} {"path":>13} {"entered [s]":>11} {"left [s]":>9} {"demands":>7} '
        f'{"ok":>4} {"pos err [mm]":>12} {"latency [ms]":>12}'
    )
    lines = [head, '-' * len(head)]
    rows = list(doc['objects']) + [{'id': None}]
    for o in rows:
        ds = [d for d in doc['demands'] if o['id'] is None or d['object'] == o['id']]
        ok = [d for d in ds if d['status'] == 'ok']
        err = [d['position_error'] for d in ok if d['position_error'] is not None]
        lat = [d['latency'] for d in ds if d.get('latency') is not None]

        def num(v: float | None, w: int, scale: float = 1.0, fmt: str = '.3f') -> str:
            return f'{"-":>{w}}' if v is None else f'{v * scale:>{w}{fmt}}'

        med_err = statistics.median(err) if err else None
        med_lat = statistics.median(lat) if lat else None
        if o['id'] is None:
            lines.append('-' * len(head))
            name, kind, entered, left = 'all', '', None, None
        else:
            name, kind, entered, left = str(o['id']), str(o['path_kind']), o['entered'], o['left']
        lines.append(
            f'{name:>6} {kind:>13} {num(entered, 11, fmt=".1f")} {num(left, 9, fmt=".1f")} '
            f'{len(ds):>7} {len(ok):>4} {num(med_err, 12, 1e3)} {num(med_lat, 12, 1e3, ".0f")}'
        )
    return '\n'.join(lines)


def _top_view(doc: dict[str, Any], path: Path) -> Path:
    """The table from above: every object's demand points (true, and the estimates), each
    object in its colour, failed demands marked, and the cell's obstacles."""
    # matplotlib (heavy) only when a figure is drawn
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.add_patch(Rectangle((0.0, 0.0), 0.5, 0.2, fill=False, lw=1.0, color='0.4'))
    for o in doc.get('obstacles') or []:
        c = o['centre']
        if o['kind'] == 'box':
            dx, dy = o['size'][0], o['size'][1]
            ax.add_patch(Rectangle((c[0] - dx / 2, c[1] - dy / 2), dx, dy, color='0.5'))
        else:
            ax.add_patch(Circle((c[0], c[1]), o['radius'], color='0.5'))
    for o in doc['objects']:
        ds = sorted((d for d in doc['demands'] if d['object'] == o['id']), key=lambda d: d['t'])
        xy = np.array([d['true_position'][:2] for d in ds if d.get('true_position')])
        if len(xy) == 0:
            continue
        (line,) = ax.plot(xy[:, 0], xy[:, 1], '-o', ms=3, lw=1, label=f'object {o["id"]}')
        est = np.array([d['estimated_position'][:2] for d in ds if d.get('estimated_position')])
        if len(est):
            ax.plot(est[:, 0], est[:, 1], 'x', ms=4, color=line.get_color())
        bad = np.array(
            [d['true_position'][:2] for d in ds if d['status'] != 'ok' and d.get('true_position')]
        )
        if len(bad):
            ax.plot(bad[:, 0], bad[:, 1], 'o', ms=9, mfc='none', color='red')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m] (cameras below, at y < 0)')
    low = [o['centre'][1] - 0.05 for o in doc.get('obstacles') or []]
    ax.set_ylim(min([-0.05, *low]), 0.22)
    ax.grid(alpha=0.3)
    if doc['objects']:
        ax.legend(fontsize=7, ncol=4, loc='lower left')
    ax.set_title('demand points (o), estimates (x), failed (red), obstacles (grey)', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_surveil_report(doc: dict[str, Any], out_dir: Path) -> Path:
    """``report.md`` and ``session.png`` (error and latency of every demand over time)."""
    # matplotlib (heavy) only when a figure is drawn
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for o in doc['objects']:
        ds = [d for d in doc['demands'] if d['object'] == o['id']]
        ts = [d['t'] for d in ds]
        err = [np.nan if d['position_error'] is None else 1e3 * d['position_error'] for d in ds]
        lat = [np.nan if d.get('latency') is None else 1e3 * d['latency'] for d in ds]
        label = f'object {o["id"]} ({o["path_kind"]})'
        axes[0].plot(ts, err, 'o', ms=4, label=label)
        axes[1].plot(ts, lat, 'o', ms=4)
    axes[0].set_ylabel('position error [mm]')
    axes[1].set_ylabel('latency [ms]')
    axes[1].set_xlabel('simulated time [s]')
    for ax in axes:
        ax.grid(alpha=0.3)
    if doc['objects']:
        axes[0].legend(fontsize=7, ncol=3)
    fig.tight_layout()
    png = out_dir / 'session.png'
    fig.savefig(png, dpi=90)
    plt.close(fig)
    top = _top_view(doc, out_dir / 'scene_top.png')
    s = doc['summary']
    title = f'Set {doc["set"]}' if doc.get('set') else 'continuous surveillance'
    gospa = s.get('gospa_mean')
    blocked = sum(1 for d in doc['demands'] if d.get('occluded'))
    n_obstacles = len(doc.get('obstacles') or [])
    lines = [
        f'# activesurv {title}',
        '',
        f'{s["objects"]} objects, {s["demands"]} demands ({doc["demand_mode"]}), '
        f'{s["ok"]} ok, over {doc["simulated_seconds"]:.0f} s of simulated time; '
        f'system {doc["system"]}, seed {doc["seed"]}; '
        + (
            f'{n_obstacles} obstacle{"" if n_obstacles == 1 else "s"}'
            if n_obstacles
            else 'no obstacle'
        )
        + ' in the cell.',
        '',
        f'Overhead tracking: at most {s.get("max_objects_at_once")} objects at once, '
        f'{s.get("id_switches")} id switches, GOSPA mean '
        + ('-' if gospa is None else f'{1e3 * gospa:.2f} mm')
        + f'. Demands with an assigned camera whose view was blocked at the instant: {blocked}.',
        '',
        'Failed demands:',
        '',
    ]
    failed = [d for d in doc['demands'] if d['status'] != 'ok']
    lines += [
        f'- demand {d["index"]} (object {d["object"]}): {d["status"]}: {d["reason"]}'
        for d in failed
    ] or ['- none']
    lines += ['', '```', session_table(doc), '```', '', f'![session]({png.name})', '']
    lines += [f'![objects and obstacles seen from above]({top.name})', '']
    path = out_dir / 'report.md'
    path.write_text('\n'.join(lines))
    return path
