"""Lockstep mode: the same cores as the node graph, stepped in one process without DDS.

Each overhead frame period (10 Hz) the loop:

1. moves the xy table, renders the overhead frame, and feeds the overhead fix to the Kalman
   predictor (activesurv_prediction);
2. predicts the rolling horizon and plans assignments and poses (activesurv_dispatch);
3. sends the stage goals to simulated stages (activesurv_stages kinematics);
4. at each demand instant, in the period it falls in, renders every assigned camera's frame
   with the stages and the object exactly as they are then, measures the marker
   (activesurv_imaging) and fuses the observations with Optimal Region (activesurv_fusion).

It is deterministic for a seed, and fast enough for Monte Carlo studies over many seeds.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.experiments.experiment import Experiment
from activesurv_bringup.experiments.faults import Fault, FaultKind
from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.occlusion import Obstacle, sight_blocked
from activesurv_common.statuses import ObservationStatus
from activesurv_dispatch.motion import Capture
from activesurv_dispatch.planner import Demand
from activesurv_dispatch.session import Dispatcher
from activesurv_evaluation.results import DemandRecord, PredictionLog, observed_visibility
from activesurv_evaluation.tracking import Snapshot
from activesurv_fusion.collector import Answer, DemandBatch, camera_answer, resolve
from activesurv_fusion.config import FusionConfig
from activesurv_imaging.capture import CaptureCore
from activesurv_imaging.overhead import overhead_fix
from activesurv_prediction.session import PredictionSession
from activesurv_sim.frame_optics import IDEAL_OPTICS, FrameOptics
from activesurv_sim.optics import Optics, frame_optics
from activesurv_sim.render import Renderer, SensorNoise
from activesurv_sim.sim_camera import object_scene, obstacle_plates
from activesurv_stages.errors import LimitError
from activesurv_stages.kinematics import AxisSimulator

Array = NDArray[np.float64]
Progress = Callable[[int, int, float], None]


@dataclass
class _Camera:
    axes: list[AxisSimulator]
    renderer: Renderer  # the true optics
    mount: CameraMount  # the true mount (with the rig's stage errors)
    imager: CaptureCore[NDArray[np.uint8]]  # what the system believes
    lens: Optics | None = None  # depth of field, exposure, response (None: a pinhole)
    first_frame: NDArray[np.uint8] | None = None

    def joints(self, t: float) -> Array:
        return np.array([ax.state(t)[0] for ax in self.axes])

    def pose(self, t: float) -> Transform:
        """Where the camera really is at ``t``."""
        return self.mount.pose_from_joints(self.joints(t))


def _state_vector(exp: Experiment, t: float) -> Array:
    s = exp.table().state(t)
    return np.concatenate([s.top, s.side, s.side_normal])


def _optics(
    exp: Experiment,
    camera: CameraModel,
    lens: Optics | None,
    pose_at: Callable[[float], Transform],
    marker: slice,
    t: float,
) -> FrameOptics:
    """What the lens and the shutter do to a frame exposed around ``t`` (centred): the depth
    of field at the marker's distance, its streak from the camera's and the object's motion."""
    if lens is None:
        return IDEAL_OPTICS
    h = lens.exposure_time / 2.0
    ends = tuple((pose_at(u), _state_vector(exp, u)[marker]) for u in (t - h, t + h))
    return frame_optics(
        camera, lens, pose_at(t), _state_vector(exp, t)[marker], (ends[0], ends[1])
    )


def run_lockstep(
    exp: Experiment,
    faults: Sequence[Fault] = (),
    progress: Progress | None = None,
    plan_log: list[tuple[int, tuple[str, ...]]] | None = None,
    track_log: list[tuple[Snapshot, Snapshot]] | None = None,
) -> list[DemandRecord]:
    """Run one experiment; returns one record per demand instant.

    Args:
        exp: the experiment.
        faults: camera faults to inject.
        progress: called as ``progress(demand_number, demands, sim_time)`` after each demand.
        plan_log: if given, receives (demand index, assigned cameras) of every capture.
        track_log: if given, receives the overhead tracks and the truth at every frame
            (:func:`activesurv_evaluation.tracking.track_metrics`).
    """
    rng = np.random.default_rng(exp.seed)
    noise = SensorNoise()
    geometry = exp.object_model
    by_cam = {f.camera: f for f in faults}
    dead = {c for c, f in by_cam.items() if f.kind is FaultKind.DEAD}

    # Prediction
    true_over, T_over = exp.overhead(truth=True)
    over_cam, T_over_believed = exp.overhead(truth=False)
    over_renderer = Renderer(true_over)
    over_lens = exp.rig.rig.overhead_lens if exp.rig is not None else None
    # The same session core as the predictor node.
    session = PredictionSession(exp.predictor_config())
    tracker = session.tracker

    # Dispatch, stages and imagers: the same session cores as the nodes (lockstep hears every
    # camera every step: liveness never expires).
    dispatcher = Dispatcher(exp.setup, exp.model, exp.dispatcher_config(math.inf))
    cameras = _cameras(exp, by_cam, dead)
    fusion = exp.fusion_config()
    truth_obstacles = exp.rig.rig.obstacles if exp.rig is not None else ()
    fixtures = obstacle_plates(truth_obstacles)  # what the cameras really see

    records: dict[int, DemandRecord] = {}
    predicted = PredictionLog()
    dt = 1.0 / exp.overhead_rate
    latency = exp.plan_latency
    if not 0.0 <= latency < dt:
        raise ConfigError(f'lockstep plan_latency must be in [0, {dt:g}) s, got {latency:g}')
    n_steps = int(np.ceil(exp.end_time / dt)) + 1
    for step in range(n_steps):
        t = step * dt
        state = _state_vector(exp, t)
        lens = _optics(exp, true_over, over_lens, lambda _: T_over, slice(0, 3), t)
        img = over_renderer.render(
            T_over, object_scene(state, geometry, fixtures), noise, rng, lens
        )
        fix = overhead_fix(
            img, over_cam, T_over_believed, exp.object_model.top_height, exp.setup.marker_radius
        )
        if fix.xy is not None:
            session.on_fix(t, fix.xy)
        session.tick(t)
        if track_log is not None:
            track_log.append(_snapshots(tracker, t, state))
        now_horizon = session.horizon(t)
        horizon: list[Demand] = []
        for p in now_horizon.demands:
            horizon.append(Demand(p.index, p.instant, p.position, p.normal, p.covariance))
            predicted.add(t, p.index, p.position, p.covariance)
        # The dispatcher decides ``latency`` after the frame, as the graph's does.
        now = t + latency
        for c, cam in cameras.items():
            dispatcher.on_joints(c, cam.joints(now), now)
        out = dispatcher.set_horizon(
            horizon, now, manoeuvres=now_horizon.motion.manoeuvre_count, stamp=t
        )
        out.merge(dispatcher.tick(now, serviced_until=t + dt - 1e-9))
        for cmd in out.goals:
            for ax, goal, v in zip(
                cameras[cmd.camera_id].axes, cmd.positions, cmd.max_velocities, strict=True
            ):
                with contextlib.suppress(LimitError):  # planned poses are inside the limits
                    ax.command(now, float(goal), float(v))
        if plan_log is not None:
            plan_log.extend((c.demand.index, c.cameras) for c in out.captures)
        for done in out.serviced:
            records[done.demand.index] = _capture(
                exp, done, cameras, by_cam, rng, noise, geometry, fusion, truth_obstacles
            )
            if progress:
                progress(len(records), len(exp.demand_times), done.demand.time)

    return _every_demand(exp, records, predicted)


def _cameras(exp: Experiment, by_cam: dict[str, Fault], dead: set[str]) -> dict[str, _Camera]:
    """The simulated stages, renderer and capture core of every camera that is alive."""
    return {
        s.camera_id: _Camera(
            [
                AxisSimulator(lim, float(q), 0.0)
                for lim, q in zip(s.limits, exp.setup.initial[s.camera_id], strict=True)
            ],
            Renderer(exp.true_camera(s.camera_id)[0]),
            exp.true_camera(s.camera_id)[1],
            CaptureCore(
                exp.imager_config(s.camera_id, by_cam.get(s.camera_id)),
                s.mount,
                exp.model,
                _identity,
                s.camera,
            ),
            exp.rig.rig.camera(s.camera_id).lens if exp.rig is not None else None,
        )
        for s in exp.setup.sensors
        if s.camera_id not in dead
    }


def _snapshots(tracker: Any, t: float, state: Array) -> tuple[Snapshot, Snapshot]:
    """The overhead tracks and the truth at ``t`` (for the tracking metrics)."""
    seen = tracker.estimates(t, tracker.tracks_started)
    present = tracker.workspace.contains(state[:2])  # on the table, not parked
    return (
        Snapshot(t, tuple((e.object_id, float(e.xy[0]), float(e.xy[1])) for e in seen)),
        Snapshot(t, ((1, float(state[0]), float(state[1])),) if present else ()),
    )


def _every_demand(
    exp: Experiment, records: dict[int, DemandRecord], predicted: PredictionLog
) -> list[DemandRecord]:
    """A record for every demand of the experiment (those never captured say so)."""
    out_records = []
    for d in exp.demands_on(expected=False):
        r = records.get(d.index)
        if r is None:
            r = DemandRecord(
                d.index,
                d.time,
                d.position,
                d.normal,
                status='not_captured',
                reason='the demand passed before a track and an assignment existed',
            )
        r.predictions = predicted.picks(d.index, d.time)
        out_records.append(r)
    return out_records


def _identity(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return image


def _capture(
    exp: Experiment,
    capture: Capture,
    cameras: dict[str, _Camera],
    faults: dict[str, Fault],
    rng: np.random.Generator,
    noise: SensorNoise,
    geometry: ObjectGeometry,
    fusion: FusionConfig,
    obstacles: Sequence[Obstacle] = (),
) -> DemandRecord:
    started = time.perf_counter()
    tj = capture.demand.time
    truth = exp.table().state(tj)
    scene = object_scene(
        np.concatenate([truth.top, truth.side, truth.side_normal]),
        geometry,
        obstacle_plates(obstacles),
    )
    occluded = []
    answers: dict[str, Answer] = {}
    poses: dict[str, Array] = {}
    offsets: dict[str, float] = {}
    for cid in capture.cameras:
        if cid not in cameras:
            continue  # a dead camera: no answer
        cam = cameras[cid]
        q = cam.joints(tj)
        T = cam.mount.pose_from_joints(q)  # where the camera really is
        if (
            obstacles
            and sight_blocked(
                T.t, truth.side, obstacles, exp.setup.marker_radius, truth.side_normal
            )[0]
        ):
            occluded.append(cid)
        lens = _optics(exp, cam.renderer.camera, cam.lens, cam.pose, slice(3, 6), tj)
        img = cam.renderer.render(T, scene, noise, rng, lens)
        fault = faults.get(cid)
        if fault is not None and fault.kind is FaultKind.FROZEN:
            if cam.first_frame is None:
                cam.first_frame = img
            img = cam.first_frame
        # The imager's own rule: the frame at t_j and the stage state at t_j.
        cam.imager.request(
            capture.demand.index, tj, capture.demand.normal, position=capture.demand.position
        )
        cam.imager.add_frame(tj, img)
        cam.imager.add_joints(tj, q)
        obs = cam.imager.poll(tj)[0]
        offsets[cid] = obs.frame_offset
        ok = obs.status is ObservationStatus.OK
        answers[cid] = camera_answer(
            cid,
            ok,
            obs.position,
            obs.normal,
            obs.covariance,
            obs.reason or f'status {obs.status.value}',
        )
        if ok and obs.position is not None:
            poses[cid] = q  # it imaged the marker: it counts for the observed visibility
    batch = DemandBatch(capture.demand.index, tj, tuple(capture.cameras), answers)
    result = resolve(batch, z=fusion.z_sigma, max_faulty=fusion.faulty_limit)
    rec = DemandRecord(capture.demand.index, tj, truth.side.copy(), truth.side_normal.copy())
    rec.assigned = list(capture.cameras)
    rec.missing = list(result.cameras_missing)
    rec.status = result.status.label
    rec.reason = result.reason
    rec.visibility = observed_visibility(
        exp.setup, exp.model, poses, truth.side, truth.side_normal
    )
    if result.fused is not None:
        rec.estimated_position = result.fused.position.copy()
        rec.estimated_normal = result.fused.normal.copy()
        rec.cameras = list(result.fused.cameras_used)
        rec.faulty = list(result.fused.cameras_faulty)
    rec.frame_offsets = offsets
    rec.occluded = occluded
    rec.latency = time.perf_counter() - started
    return rec
