"""Where dispatching several objects breaks: cameras per demand as objects grow, with 4 or 8
cameras (issue 27's study), in a dispatch lockstep.

The dispatcher's session core (:class:`~activesurv_dispatch.session.Dispatcher`) serves a seeded
stream of N objects at once (:class:`~activesurv_sim.stream.ObjectStream`, lanes), each demanded
every ``interval`` s while it is in the demand region, the objects' instants staggered by
interval / N. (The stagger is a fixed grid per lane here; ``surveil --objects-at-once N``'s
predictor, :class:`~activesurv_prediction.multi.MultiTracker`, picks each new object's phase
farthest from the others' when it is confirmed, to the same spacing.) It is told the truth (a
perfect predictor: the study is of the cameras, not of the tracking); the stages move as the
motion class lets them (:class:`~activesurv_stages.kinematics.AxisSimulator`); nothing is
rendered: each capture's cameras are judged by eq. 1 at the pose they really had at the instant,
the other objects' marker plates standing in the way. The 8-camera set-up is the paper's four and
a copy of each moved 60 mm along the table (``cam5`` .. ``cam8``).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from activesurv_common.occlusion import Obstacle, plate_box
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.best_pose import Target, view_batch
from activesurv_dispatch.initial_pose import initial_poses
from activesurv_dispatch.planner import Demand
from activesurv_dispatch.sensors import Sensor, Setup, load_setup
from activesurv_dispatch.session import Dispatcher, DispatcherConfig
from activesurv_sim.stream import ObjectStream
from activesurv_stages.errors import LimitError
from activesurv_stages.kinematics import AxisSimulator

Array = NDArray[np.float64]
REGION = (0.10, 0.40)  # x where demands are made (the surveil default)
COPY_SHIFT = 0.06  # m along the table between a camera and its copy


def eight_cameras(setup: Setup) -> Setup:
    """The set-up with a copy of each camera moved ``COPY_SHIFT`` along the table."""
    copies: list[Sensor] = []
    initial = dict(setup.initial)
    for i, s in enumerate(setup.sensors):
        cid = f'cam{len(setup.sensors) + i + 1}'
        m = s.mount
        mount = replace(
            m,
            camera_id=cid,
            base=m.base + np.array([COPY_SHIFT, 0.0, 0.0]),
            linear_joint=None if m.linear_joint is None else f'{cid}_x',
            rotary_joint=f'{cid}_yaw',
        )
        copies.append(replace(s, camera_id=cid, mount=mount))
        initial[cid] = np.array(setup.initial[s.camera_id], dtype=float)
    return replace(setup, sensors=(*setup.sensors, *copies), initial=initial)


@dataclass
class _Demand:
    index: int
    time: float
    object_id: int


def _demands(stream: ObjectStream, n: int, interval: float, until: float) -> list[_Demand]:
    out: list[tuple[float, int]] = []
    for p in stream.passes:
        # On the lane's grid: lanes' instants interval / n apart, whenever objects enter.
        phase = p.slot * interval / n
        t = phase + interval * np.ceil((p.entered + interval - phase) / interval)
        while t <= min(p.left, until):
            x = stream.slot_state(p.slot, t)[1].top[0]
            if REGION[0] <= x <= REGION[1]:
                out.append((t, p.id))
            t += interval
    out.sort()
    return [_Demand(j, t, oid) for j, (t, oid) in enumerate(out)]


def run_scaling(
    objects: int,
    cameras: int = 4,
    seconds: float = 120.0,
    interval: float = 2.0,
    seed: int = 1,
    system: str = 'fast',
    k: int = 3,
) -> dict[str, Any]:
    """One run: ``objects`` at once, ``cameras`` (4 or 8); returns the figures per demand.

    Returns:
        ``demands``, ``cameras_per_demand`` (assigned cameras that see the marker at the instant,
        mean), ``assigned_per_demand``, ``full_fraction`` (demands seen by k cameras) and
        ``none_fraction`` (by none).
    """
    model = SensorModel.load()
    setup = load_setup(motion=system)
    if cameras == 8:
        setup = eight_cameras(setup)
    elif cameras != 4:
        raise ValueError(f'the study has 4 or 8 cameras, not {cameras}')
    stream = ObjectStream(seed, arrival_interval=30.0, first_entry=1.0, at_once=objects)
    stream.passes_at(seconds + 60.0)  # draw the objects
    demands = _demands(stream, objects, interval, seconds)
    if not demands:
        return {'demands': 0}
    by_index = {d.index: d for d in demands}

    def truth(d: _Demand) -> tuple[Array, Array]:
        p = next(q for q in stream.passes if q.id == d.object_id)
        s = stream.slot_state(p.slot, d.time)[1]
        return s.side, s.side_normal

    # Initial poses placed for the first few demands' points (as a session's are).
    first = [Demand(d.index, d.time, *truth(d), np.eye(6) * 1e-6) for d in demands[:6]]
    setup = setup.with_initial(initial_poses(setup, model, first, 0.0, k))
    axes = {
        s.camera_id: [
            AxisSimulator(lim, float(q), 0.0)
            for lim, q in zip(s.limits, setup.initial[s.camera_id], strict=True)
        ]
        for s in setup.sensors
    }

    def joints(cid: str, t: float) -> Array:
        return np.array([ax.state(t)[0] for ax in axes[cid]])

    dispatcher = Dispatcher(setup, model, DispatcherConfig(k, 1.0, 0.3, 0.1, float('inf')))
    dt, cov = 0.1, np.diag([1e-7, 1e-7, 1e-7, 1e-4, 1e-4, 1e-4])
    seen: dict[int, int] = {}
    assigned: dict[int, int] = {}
    t = 0.0
    while t < seconds + 2.0:
        horizon: list[Demand] = []
        for d in demands:
            if d.time > t and len(horizon) < 5:
                pos, nrm = truth(d)
                horizon.append(Demand(d.index, d.time, pos, nrm, cov, d.object_id))
        for c in axes:
            dispatcher.on_joints(c, joints(c, t), t)
        out = dispatcher.set_horizon(horizon, t, stamp=t)
        out.merge(dispatcher.tick(t, serviced_until=t + dt - 1e-9))
        for cmd in out.goals:
            for ax, goal, v in zip(
                axes[cmd.camera_id], cmd.positions, cmd.max_velocities, strict=True
            ):
                with contextlib.suppress(LimitError):
                    ax.command(t, float(goal), float(v))
        for done in out.serviced:
            d = by_index[done.demand.index]
            pos, nrm = truth(d)
            others: list[Obstacle] = []
            for p in stream.passes_at(d.time):
                if p.id != d.object_id:
                    o = stream.slot_state(p.slot, d.time)[1]
                    others.append(plate_box(o.side, o.side_normal, setup.object_half_size))
            target = Target(pos, nrm)
            n_seen = 0
            for c in done.cameras:
                q = joints(c, d.time)[None, :]
                vis = view_batch(
                    setup.sensor(c), q, target, setup.marker_radius, model, occluders=others
                )[0]
                n_seen += int(vis[0] > 0.0)
            seen[d.index], assigned[d.index] = n_seen, len(done.cameras)
        t += dt
    n = len(demands)
    counts = [seen.get(d.index, 0) for d in demands]
    return {
        'demands': n,
        'cameras_per_demand': round(float(np.mean(counts)), 3),
        'assigned_per_demand': round(
            float(np.mean([assigned.get(d.index, 0) for d in demands])), 3
        ),
        'full_fraction': round(sum(c >= k for c in counts) / n, 3),
        'none_fraction': round(sum(c == 0 for c in counts) / n, 3),
    }
