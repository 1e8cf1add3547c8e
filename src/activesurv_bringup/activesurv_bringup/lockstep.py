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
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from activesurv_bringup.evaluation import DemandRecord, observed_visibility
from activesurv_bringup.experiment import Experiment
from activesurv_bringup.faults import Fault
from activesurv_dispatch.motion import Capture, CaptureScheduler, MotionController
from activesurv_dispatch.planner import Demand, DispatchPlanner
from activesurv_fusion.collector import Answer, DemandBatch, Outcome, resolve
from activesurv_fusion.errors import InvalidReadingError
from activesurv_fusion.pose_fusion import PoseReading
from activesurv_imaging.camera_model import overhead_camera
from activesurv_imaging.geometry import Transform, matrix_from_quaternion
from activesurv_imaging.observation import ObservationStatus, observe_marker, perturb
from activesurv_imaging.render import Renderer, SensorNoise
from activesurv_imaging.sim_camera import ObjectGeometry, object_scene
from activesurv_prediction.demands import DemandSchedule, TargetGeometry, predict_demands
from activesurv_prediction.overhead import overhead_fix
from activesurv_prediction.predictor import TargetPredictor
from activesurv_prediction.tracker import Tracker, TrackState, Workspace
from activesurv_stages.errors import LimitError
from activesurv_stages.kinematics import AxisSimulator

Array = NDArray[np.float64]
Progress = Callable[[int, int, float], None]


@dataclass
class _Camera:
    axes: list[AxisSimulator]
    renderer: Renderer
    first_frame: NDArray[np.uint8] | None = None

    def joints(self, t: float) -> Array:
        return np.array([ax.state(t)[0] for ax in self.axes])


def _state_vector(exp: Experiment, t: float) -> Array:
    s = exp.table().state(t)
    return np.concatenate([s.top, s.side, s.side_normal])


def run_lockstep(
    exp: Experiment,
    faults: Sequence[Fault] = (),
    progress: Progress | None = None,
    plan_log: list[tuple[int, tuple[str, ...]]] | None = None,
) -> list[DemandRecord]:
    """Run one experiment; returns one record per demand instant.

    Args:
        exp: the experiment.
        faults: camera faults to inject.
        progress: called as ``progress(demand_number, demands, sim_time)`` after each demand.
        plan_log: if given, receives (demand index, assigned cameras) of every capture.
    """
    cfg = exp.config
    rng = np.random.default_rng(exp.seed)
    noise = SensorNoise()
    geometry = ObjectGeometry(exp.setup.marker_radius, exp.setup.marker_radius)
    by_cam = {f.camera: f for f in faults}
    dead = {c for c, f in by_cam.items() if f.kind == 'dead'}

    # Prediction
    pose = [float(v) for v in cfg['overhead']['pose']]
    T_over = Transform.from_rt(matrix_from_quaternion(pose[3:]), pose[:3])
    over_cam = overhead_camera()
    over_renderer = Renderer(over_cam)
    pc = cfg['predictor']
    tracker = Tracker(
        TargetPredictor(
            measurement_std=float(pc['measurement_std']), jerk_std=float(pc['jerk_std'])
        ),
        Workspace(),
        confirm_fixes=int(pc['confirm_fixes']),
    )
    schedule = DemandSchedule.explicit(exp.demand_times)
    om = exp.object_model
    target_geo = TargetGeometry.create(om.side_offset, om.side_normal)

    # Dispatch and stages
    dc = cfg['dispatch']
    planner = DispatchPlanner(
        exp.setup, exp.model, int(cfg['k']), float(dc['rho']), float(dc['settle_time'])
    )
    motion = MotionController(exp.setup)
    scheduler = CaptureScheduler(float(dc['capture_lead']))
    cameras = {
        s.camera_id: _Camera(
            [
                AxisSimulator(lim, float(q), 0.0)
                for lim, q in zip(s.limits, exp.setup.initial[s.camera_id], strict=True)
            ],
            Renderer(s.camera),
        )
        for s in exp.setup.sensors
        if s.camera_id not in dead
    }
    z_sigma = float(cfg['fusion']['z_sigma'])

    demands: dict[int, Demand] = {}
    records: dict[int, DemandRecord] = {}
    dt = 1.0 / float(cfg['overhead']['rate'])
    n_steps = int(np.ceil(exp.end_time / dt)) + 1
    for step in range(n_steps):
        t = step * dt
        state = _state_vector(exp, t)
        img = over_renderer.render(T_over, object_scene(state, geometry), noise, rng)
        fix = overhead_fix(img, over_cam, T_over, om.top_height, exp.setup.marker_radius)
        if fix.xy is not None:
            tracker.update(t, fix.xy)
        tracker.check_timeout(t)
        horizon: list[Demand] = []
        if tracker.state in (TrackState.TENTATIVE, TrackState.CONFIRMED):
            for p in predict_demands(
                tracker.predictor, schedule, target_geo, om.top_height, t, int(pc['horizon'])
            ):
                d = Demand(p.index, p.instant, p.position, p.normal, p.covariance)
                demands[d.index] = d
                horizon.append(d)
        joints = {c: cam.joints(t) for c, cam in cameras.items()}
        plan = planner.plan(t, horizon, joints)
        for cmd in motion.commands(plan, demands):
            for ax, goal, v in zip(
                cameras[cmd.camera_id].axes, cmd.positions, cmd.max_velocities, strict=True
            ):
                with contextlib.suppress(LimitError):  # planned poses are inside the limits
                    ax.command(t, float(goal), float(v))
        capture = scheduler.due(t, plan, demands)
        if capture is not None:
            planner.close(capture.demand.index)
            motion.holding.update(capture.cameras)
            if plan_log is not None:
                plan_log.append((capture.demand.index, capture.cameras))
        for done in scheduler.newly_serviced(t + dt - 1e-9):
            records[done.demand.index] = _capture(
                exp, done, cameras, by_cam, rng, noise, geometry, z_sigma, dead
            )
            planner.serviced(done.demand.index)
            motion.holding.difference_update(done.cameras)
            if progress:
                progress(len(records), len(exp.demand_times), done.demand.time)

    truth = exp.demands_on(expected=False)
    out = []
    for d in truth:
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
        out.append(r)
    return out


def _capture(
    exp: Experiment,
    capture: Capture,
    cameras: dict[str, _Camera],
    faults: dict[str, Fault],
    rng: np.random.Generator,
    noise: SensorNoise,
    geometry: ObjectGeometry,
    z_sigma: float,
    dead: set[str],
) -> DemandRecord:
    started = time.perf_counter()
    tj = capture.demand.time
    truth = exp.table().state(tj)
    scene = object_scene(np.concatenate([truth.top, truth.side, truth.side_normal]), geometry)
    answers: dict[str, Answer] = {}
    poses: dict[str, Array] = {}
    for cid in capture.cameras:
        if cid in dead or cid not in cameras:
            continue
        cam = cameras[cid]
        sensor = exp.setup.sensor(cid)
        q = cam.joints(tj)
        T = (
            sensor.mount.camera_pose(float(q[0]), float(q[1]))
            if sensor.has_linear
            else sensor.mount.camera_pose(0.0, float(q[0]))
        )
        fault = faults.get(cid)
        img = cam.renderer.render(T, scene, noise, rng)
        if fault is not None and fault.kind == 'frozen':
            if cam.first_frame is None:
                cam.first_frame = img
            img = cam.first_frame
        obs = observe_marker(
            img,
            sensor.camera,
            T,
            exp.setup.marker_radius,
            exp.model,
            cid,
            capture.demand.index,
            tj,
            capture.demand.normal,
            fault is not None and fault.kind == 'flip',
        )
        if fault is not None and fault.kind in ('bias', 'noise'):
            obs = perturb(
                obs,
                fault.magnitude if fault.kind == 'bias' else 0.0,
                fault.magnitude if fault.kind == 'noise' else 0.0,
                rng,
            )
        if (
            obs.status is not ObservationStatus.OK
            or obs.position is None
            or obs.normal is None
            or obs.covariance is None
        ):
            answers[cid] = Answer(cid, Outcome.FAILED, None, f'{obs.status.name}: {obs.reason}')
            continue
        poses[cid] = q  # it imaged the marker: it counts for the observed visibility
        try:
            reading = PoseReading.create(cid, obs.position, obs.normal, obs.covariance)
            answers[cid] = Answer(cid, Outcome.OK, reading)
        except InvalidReadingError as exc:
            answers[cid] = Answer(cid, Outcome.FAILED, None, str(exc))
    batch = DemandBatch(capture.demand.index, tj, tuple(capture.cameras), answers)
    result = resolve(batch, z=z_sigma)
    rec = DemandRecord(capture.demand.index, tj, truth.side.copy(), truth.side_normal.copy())
    rec.assigned = list(capture.cameras)
    rec.missing = list(result.cameras_missing)
    rec.status = result.status.name.lower()
    rec.reason = result.reason
    rec.visibility = observed_visibility(
        exp.setup, exp.model, poses, truth.side, truth.side_normal
    )
    if result.fused is not None:
        rec.estimated_position = result.fused.position.copy()
        rec.estimated_normal = result.fused.normal.copy()
        rec.cameras = list(result.fused.cameras_used)
        rec.faulty = list(result.fused.cameras_faulty)
    rec.latency = time.perf_counter() - started
    return rec
