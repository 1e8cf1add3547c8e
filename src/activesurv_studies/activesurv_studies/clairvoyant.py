"""What a clairvoyant dispatcher would have got, and an occlusion-blind greedy one, per demand.

For each demand of a recorded simulated run, every camera starts where its stage really was at
the previous demand's instant (the run's first demand: 1 s before) and has until this demand's
instant, less the settle time, to move:

* **clairvoyant**: knows the true marker (position, normal) and the true occluders (the cell's
  obstacles and the other objects' marker plates at the instant); each camera takes its best
  achievable pose for it (eq. 1 with occlusion), and the best k cameras that see it are taken;
* **greedy, occlusion-blind**: the same from the truth, but choosing the k best poses as if
  nothing stood in the way; what it then really sees counts (a blocked camera adds nothing).

The figures (``compare``) set the run's own assignment against both: cameras per demand and
fused visibility (eq. 2; the run's is that of the assigned cameras that imaged the marker).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from activesurv_common.occlusion import (
    PLATE_HALF_SIZE,
    Obstacle,
    obstacles_from_list,
    plate_box,
)
from activesurv_common.sensor_model import SensorModel
from activesurv_common.timeseries import TimeSeries
from activesurv_dispatch.best_pose import Target, best_achievable_pose, view_batch
from activesurv_dispatch.sensors import Setup, setup_from_dict
from activesurv_evaluation.results import observed_visibility
from activesurv_recording.bagio import read_bag
from activesurv_recording.errors import BagError
from activesurv_recording.run_record import read_run_record

K = 3


def compare(run_dir: Path, k: int = K) -> dict[str, Any]:
    """The run's assignment against the clairvoyant and greedy ones (see the module).

    Raises:
        BagError: for a run without the believed set-up (``rig/setup.yaml``) or results.
    """
    try:
        doc = json.loads((run_dir / 'results.json').read_text())
        setup_data = yaml.safe_load((run_dir / 'rig' / 'setup.yaml').read_text())
    except (OSError, ValueError, yaml.YAMLError) as exc:
        raise BagError(f'{run_dir}: no results.json or rig/setup.yaml: {exc}') from exc
    bag = run_dir / 'bag'
    record = read_run_record(bag)
    setup = setup_from_dict(setup_data, record.system)
    model = SensorModel.load()
    obstacles = list(obstacles_from_list(list(record.obstacles)))
    joints, lanes = _recorded_states(bag, setup)
    origin = record.time_origin
    settle = 0.1
    rows = []
    previous = None
    for d in sorted(doc['demands'], key=lambda r: r['t']):
        if d.get('true_position') is None:
            continue
        tj = origin + float(d['t'])
        start = tj - 1.0 if previous is None else max(previous, tj - 2.0)
        previous = tj
        position = np.asarray(d['true_position'], dtype=np.float64)
        target = Target(position, np.asarray(d['true_normal'], dtype=np.float64))
        others: list[Obstacle] = []
        for series in lanes.values():
            v = series.at(tj, 0.5)
            if v is not None and v[6] > 0.5 and np.linalg.norm(v[:3] - position) > 1e-3:
                others.append(plate_box(v[:3], v[3:6], PLATE_HALF_SIZE))
        occluders: list[Obstacle] = obstacles + others
        seen, blind = {}, {}
        for s in setup.sensors:
            q0 = joints[s.camera_id].at(start, 0.5)
            if q0 is None:
                continue
            dt = tj - start - settle
            seen[s.camera_id] = best_achievable_pose(
                s, q0, target, dt, model, setup.marker_radius, 21, occluders
            )
            blind[s.camera_id] = best_achievable_pose(
                s, q0, target, dt, model, setup.marker_radius, 21
            )
        clair = sorted(
            (c for c in seen if seen[c].visibility > 0.0), key=lambda c: -seen[c].visibility
        )[:k]
        greedy = sorted(
            (c for c in blind if blind[c].visibility > 0.0), key=lambda c: -blind[c].visibility
        )[:k]
        greedy_seen = [
            c
            for c in greedy
            if view_batch(
                setup.sensor(c),
                blind[c].joints[None, :],
                target,
                setup.marker_radius,
                model,
                occluders=occluders,
            )[3][0]
        ]
        rows.append(
            {
                'index': d['index'],
                'cameras': len(d.get('cameras') or []),
                'assigned': len(d.get('assigned') or []),
                'visibility': float(d.get('visibility') or 0.0),
                'clairvoyant_cameras': len(clair),
                'clairvoyant_visibility': observed_visibility(
                    setup, model, {c: seen[c].joints for c in clair}, position, target.normal
                ),
                'greedy_cameras_seeing': len(greedy_seen),
                'greedy_visibility': observed_visibility(
                    setup,
                    model,
                    {c: blind[c].joints for c in greedy_seen},
                    position,
                    target.normal,
                ),
            }
        )
    return _summary(rows)


def _recorded_states(
    bag: Path, setup: Setup
) -> tuple[dict[str, TimeSeries], dict[int, TimeSeries]]:
    """Each camera's stage states, and each lane's object (marker, normal, on the table)."""
    joints = {s.camera_id: TimeSeries(len(s.joint_names), capacity=10**7) for s in setup.sensors}
    names = {f'/{s.camera_id}/stage/joint_states': s for s in setup.sensors}
    lanes: dict[int, TimeSeries] = {}
    for m in read_bag(bag, {*names, '/object_state'}):
        t = float(m.msg.header.stamp.sec) + 1e-9 * float(m.msg.header.stamp.nanosec)
        if m.topic == '/object_state':
            slot = int(getattr(m.msg, 'slot', 0))
            series = lanes.setdefault(slot, TimeSeries(7, capacity=10**7))
            p, n = m.msg.side_marker, m.msg.side_normal
            series.add(t, [p.x, p.y, p.z, n.x, n.y, n.z, 1.0 if m.msg.in_workspace else 0.0])
            continue
        s = names[m.topic]
        by_name = dict(zip(m.msg.name, m.msg.position, strict=False))
        if all(j in by_name for j in s.joint_names):
            joints[s.camera_id].add(t, [by_name[j] for j in s.joint_names])
    return joints, lanes


def _summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per-demand means of the run, the clairvoyant and the greedy assignments."""
    if not rows:
        return {'demands': 0}

    def mean(key: str) -> float:
        return float(np.mean([r[key] for r in rows]))

    clair_cams, clair_vis = mean('clairvoyant_cameras'), mean('clairvoyant_visibility')
    return {
        'demands': len(rows),
        'cameras_per_demand': mean('assigned'),
        'clairvoyant_cameras_per_demand': clair_cams,
        'greedy_cameras_seeing_per_demand': mean('greedy_cameras_seeing'),
        'cameras_ratio': mean('assigned') / clair_cams if clair_cams else None,
        'visibility_ratio': mean('visibility') / clair_vis if clair_vis else None,
        'greedy_visibility_ratio': mean('greedy_visibility') / clair_vis if clair_vis else None,
        'rows': rows,
    }
