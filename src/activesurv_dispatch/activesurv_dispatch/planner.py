"""Sensor dispatching: assignment, preassignment and replanning (paper Section II, III-C).

On every new rolling horizon, :meth:`DispatchPlanner.plan`:

1. **Assignment and positioning** (II-B, III-C-1). The first unserviced demand gets k cameras,
   picked by an increasingly complex iterative ranking:

   a. *A priori*: a camera that cannot see the demand from anywhere on its stages, because the
      marker faces away from every position it can take, is ranked last.
   b. *Normalised distance*: the joint-space distance from the current pose to the camera's
      ideal pose (unlimited time), divided by what the stages cover in the time left
      (``max velocity x time``). The closest ranks highest.
   c. *Visibility* (eq. 1) at the best achievable pose, computed for the best ``k + extra``
      cameras of ranking (b). The top k by visibility are assigned, except those that cannot
      see the demand at all (unless none can).

   The assignment is frozen until the demand is serviced (:meth:`serviced`). Its desired poses
   are not frozen: see 3. Ours in addition: a frozen assignment with fewer than k cameras (one
   died and was excluded, or a camera's first stage state came after the assignment) is topped
   up from the cameras not in it, by the same ranking, until its capture request has gone out
   (:meth:`close`). Cameras already in it are never swapped.
2. **Preassignment and prepositioning** (II-C). Cameras not assigned to the first demand go to
   the next demands in turn, up to k per demand, until all are placed or the horizon ends. They
   are re-planned on every horizon.
3. **Replanning** (II-D). When the predictor reports a manoeuvre (the object stopped, started
   or began to accelerate: :meth:`manoeuvre`), or when the new prediction of an assigned
   demand leaves the box
   ``|delta| <= rho * sigma`` (x, y, z) around the prediction used at assignment, the desired
   poses of its cameras are recomputed, and that prediction becomes the new reference. Ours in
   addition: also when an assigned camera's desired pose would not keep the new prediction in
   view. An assignment made early in a track has a large sigma, so the paper's box alone lets
   the cameras stay aimed at a stale prediction, and a 7-degree field of view does not forgive
   that.

Cameras with nothing to do keep their poses (idle). A static system only re-ranks; its poses are
its initial ones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from activesurv_common.geometry import angle_between
from activesurv_common.occlusion import Obstacle, plate_box, sight_blocked
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.best_pose import (
    VIEW_SIGMAS,
    Candidate,
    SingleView,
    Target,
    aim_yaw,
    best_achievable_pose,
    blur_loss,
    camera_frames,
    view_batch,
    view_one,
    visibility_at_poses,
)
from activesurv_dispatch.errors import DispatchConfigError
from activesurv_dispatch.sensors import Sensor, Setup
from activesurv_stages.kinematics import min_travel_time

Array = NDArray[np.float64]


IDEAL_BEARING = math.radians(40.0)
"""Bearing (angle between the optical axis and the marker normal) at which the packaged sensor
model's visibility peaks (40-45 deg, paper Appendix A: "between 20 and 40 deg"); the stage-2
ranking measures each camera's distance to the linear position that gives it."""


class Role(Enum):
    """Mirrors the ROLE_* constants of ``activesurv_interfaces/SensorAssignment``."""

    IDLE = 0
    ASSIGNED = 1
    PREASSIGNED = 2


@dataclass(frozen=True)
class Demand:
    """A predicted demand point (world, SI)."""

    index: int
    time: float
    position: Array
    normal: Array
    covariance: Array  # 6x6 over (x, y, z, rot_x, rot_y, rot_z)
    object_id: int = 0  # continuous surveillance: the object it surveys (0: an experiment)
    velocity: Array | None = None  # predicted marker velocity at the instant (m/s)

    @property
    def target(self) -> Target:
        """The target with its lateral (x, y) prediction uncertainty."""
        c = self.covariance
        sigma = float(np.sqrt(max(c[0, 0], c[1, 1], 0.0)))
        return Target(self.position, self.normal, sigma, self.velocity)

    def sigma(self) -> Array:
        return np.sqrt(np.maximum(np.diag(self.covariance)[:3], 0.0))


@dataclass(frozen=True)
class Assignment:
    camera_id: str
    role: Role
    demand_index: int
    desired: Array
    visibility: float


@dataclass(frozen=True)
class Plan:
    """A planning result.

    Attributes:
        stamp: planning time.
        first_index: the demand being serviced next (-1: none).
        assignments: one per camera.
        fused_visibility: v_f (eq. 2) of the assigned cameras at their desired poses.
        replanned: this plan replanned the first demand (II-D).
        ranking: camera ids of the first demand, best first, with their visibilities.
        blur_loss: of the first demand's ranked cameras (when it was ranked), the share of
            each one's visibility its predicted blur costs (:func:`best_pose.blur_loss`).
    """

    stamp: float
    first_index: int
    assignments: dict[str, Assignment]
    fused_visibility: float
    replanned: bool
    ranking: tuple[tuple[str, float], ...] = ()
    blur_loss: tuple[tuple[str, float], ...] = ()

    def assigned(self) -> list[str]:
        return [c for c, a in self.assignments.items() if a.role is Role.ASSIGNED]


@dataclass
class _Frozen:
    cameras: tuple[str, ...]
    reference: Demand
    desired: dict[str, Candidate] = field(default_factory=dict)


class DispatchPlanner:
    """Plans camera assignments and desired poses from the rolling horizon (pure core)."""

    def __init__(
        self,
        setup: Setup,
        model: SensorModel,
        k: int = 3,
        rho: float = 1.0,
        settle_time: float = 0.1,
        extra: int = 2,
        samples: int = 21,
    ) -> None:
        if k < 1:
            raise DispatchConfigError(f'k must be >= 1, got {k}')
        if not (math.isfinite(rho) and rho > 0):
            raise DispatchConfigError(f'rho must be finite and > 0, got {rho}')
        self.setup = setup
        self.model = model
        self.k = k
        self.rho = rho
        self.settle_time = settle_time
        self.extra = extra
        self.samples = samples
        self.sensors = {s.camera_id: s for s in setup.sensors}
        self._frozen: dict[int, _Frozen] = {}
        self._serviced: set[int] = set()
        self.replans = 0
        self.occlusion_swaps = 0  # cameras taken off an assignment because of occlusion
        self._manoeuvre = False
        self.excluded: set[str] = set()  # cameras judged dead: not dispatched
        self._closed: set[int] = set()  # demands whose capture request has gone out
        self._horizon: list[Demand] = []
        self._occluders: dict[int, tuple[Obstacle, ...]] = {}
        # Best poses found during the current plan (see rank).
        self._ranked: dict[tuple[str, int, float, bytes, bytes], Candidate] = {}
        # One pose's view of one demand, as the current plan weighed it (see _view).
        self._seen: dict[tuple[str, bytes, int, bytes], SingleView] = {}

    # -- bookkeeping -------------------------------------------------------------------------
    def serviced(self, index: int) -> None:
        """Demand ``index`` has been captured: release its frozen assignment."""
        self._serviced.add(index)
        self._frozen.pop(index, None)
        self._closed.discard(index)

    def close(self, index: int) -> None:
        """The capture request of demand ``index`` has gone out: its camera set is final."""
        self._closed.add(index)

    def frozen_cameras(self, index: int) -> tuple[str, ...]:
        f = self._frozen.get(index)
        return f.cameras if f else ()

    def exclude(self, camera_id: str) -> None:
        """Take a camera out of dispatching (its nodes died); its frozen slots are freed."""
        self.excluded.add(camera_id)
        for f in self._frozen.values():
            if camera_id in f.cameras:
                f.cameras = tuple(c for c in f.cameras if c != camera_id)
                f.desired.pop(camera_id, None)

    def include(self, camera_id: str) -> None:
        """Put a camera back into dispatching (its nodes are heard again)."""
        self.excluded.discard(camera_id)

    def _better(
        self, camera_id: str, old: Candidate | None, new: Candidate, demand: Demand
    ) -> Candidate:
        """Replanning never trades a desired pose for a worse one: the new best achievable
        pose is reckoned from rest at the camera's current position, so a camera still on its
        way underrates what it can reach, and re-aiming it at each new prediction would make
        it stop short (at the edge of that box) frame after frame. The old pose stays when it
        sees the new prediction better, and when neither sees it, when it points nearer to it:
        the new one, from rest where the camera is now, may lie short of where the old one
        (planned with more time) was taking it, and re-aiming there pulls the camera back from
        the target frame after frame (two objects at once: 12 of 318 demands had a camera stop
        3-5 degrees short)."""
        if old is None:
            return new
        v = self._view(camera_id, old.joints, demand)
        keep = v.visibility > new.visibility or (
            new.visibility <= 0.0
            and self._off_axis(camera_id, old.joints, demand)
            < self._off_axis(camera_id, new.joints, demand)
        )
        if keep:
            return Candidate(old.joints, v.visibility, v.distance, v.bearing, v.in_view)
        return new

    def _off_axis(self, camera_id: str, q: Array, demand: Demand) -> float:
        """Angle (rad) between the camera's optical axis at ``q`` and its line of sight to
        ``demand``'s marker."""
        centres, R = camera_frames(self.sensors[camera_id], np.asarray(q)[None, :])
        return angle_between(R[0][:, 2], demand.position - centres[0])

    def _blocked(self, camera_id: str, q: Array, demand: Demand) -> bool:
        """Whether an occluder stands between the camera at ``q`` and ``demand``'s marker."""
        occluders = self.occluders(demand)
        if not occluders:
            return False
        centre, _ = camera_frames(self.sensors[camera_id], np.asarray(q)[None, :])
        radius = self.setup.marker_radius + VIEW_SIGMAS * demand.target.sigma
        return bool(sight_blocked(centre, demand.position, occluders, radius)[0])

    def _view(self, camera_id: str, q: Array, demand: Demand) -> SingleView:
        """:func:`view_one` of camera ``camera_id`` at joints ``q`` for ``demand``, weighed
        once per plan: a plan asks it of the same frozen poses up to three times (is a replan
        needed, is the old pose better, the fused visibility)."""
        c = demand.covariance
        key = (
            camera_id,
            q.tobytes(),
            demand.index,
            b''.join(
                a.tobytes()
                for a in (demand.position, demand.normal, c, demand.velocity)
                if a is not None
            ),
        )
        seen = self._seen.get(key)
        if seen is None:
            seen = view_one(
                self.sensors[camera_id],
                q,
                demand.target,
                self.setup.marker_radius,
                self.model,
                self.occluders(demand),
            )
            self._seen[key] = seen
        return seen

    def occluders(self, demand: Demand) -> tuple[Obstacle, ...]:
        """What may stand between a camera and ``demand``'s marker: the cell's obstacles and
        the other objects on the table where they are predicted at its instant (their marker
        plates, from their own demands on the horizon, moved along their velocity)."""
        cached = self._occluders.get(demand.index)
        if cached is not None:
            return cached
        out = list(self.setup.obstacles)
        if demand.object_id:
            nearest: dict[int, Demand] = {}
            for d in self._horizon:
                if d.object_id and d.object_id != demand.object_id:
                    best = nearest.get(d.object_id)
                    if best is None or abs(d.time - demand.time) < abs(best.time - demand.time):
                        nearest[d.object_id] = d
            for d in nearest.values():
                p = d.position
                if d.velocity is not None:
                    p = p + d.velocity * (demand.time - d.time)
                out.append(plate_box(p, d.normal, self.setup.object_half_size))
        result = tuple(out)
        self._occluders[demand.index] = result
        return result

    # -- ranking -----------------------------------------------------------------------------
    def _can_ever_see(self, sensor: Sensor, demand: Demand) -> bool:
        lims = sensor.limits
        if sensor.has_linear:
            lin = np.linspace(lims[0].min_position, lims[0].max_position, 5)
        else:
            lin = np.zeros(1)
        q = np.column_stack([lin, np.zeros_like(lin)]) if sensor.has_linear else lin[:, None]
        centres, _ = camera_frames(sensor, q)
        facing = (centres - demand.position[None, :]) @ demand.normal
        return bool(np.any(facing > 0.0))

    def _normalised_distance(self, sensor: Sensor, q0: Array, demand: Demand, dt: float) -> float:
        """Joint-space distance to the ideal pose over what the stages cover in ``dt``."""
        lims = sensor.limits
        yaw_goal = aim_yaw(sensor, np.array([q0[0] if sensor.has_linear else 0.0]), demand.target)[
            0
        ]
        dist = [abs(yaw_goal - q0[-1]) / max(lims[-1].max_velocity * max(dt, 1e-3), 1e-12)]
        if sensor.has_linear:
            # The ideal linear position: where the bearing is the sensor model's optimum on the
            # camera's side, within the stage range.
            centre, _ = camera_frames(sensor, q0[None, :])
            dy = abs(demand.position[1] - centre[0, 1])
            side = 1.0 if centre[0, 0] >= demand.position[0] else -1.0
            x_goal = demand.position[0] + side * dy * math.tan(IDEAL_BEARING)
            axis = sensor.mount.linear_axis
            assert axis is not None
            s_goal = float(
                np.clip(
                    (x_goal - sensor.mount.base[0]) / (axis[0] or 1.0),
                    lims[0].min_position,
                    lims[0].max_position,
                )
            )
            dist.append(abs(s_goal - q0[0]) / max(lims[0].max_velocity * max(dt, 1e-3), 1e-12))
        return float(max(dist))

    def rank(
        self,
        demand: Demand,
        cameras: Sequence[str],
        joints: dict[str, Array],
        now: float,
        limit: int | None = None,
    ) -> list[tuple[str, Candidate]]:
        """Cameras ordered best first for ``demand``, with their best achievable poses.

        Only the best ``limit`` of the normalised-distance ranking get the full visibility
        optimisation (default: k + extra); the rest follow with zero visibility.
        """
        dt = demand.time - now - self.settle_time
        scored = []
        for cid in cameras:
            s = self.sensors[cid]
            q0 = joints[cid]
            a_priori = self._can_ever_see(s, demand)
            nd = self._normalised_distance(s, q0, demand, dt)
            scored.append((0 if a_priori else 1, nd, cid))
        scored.sort()
        n_full = len(scored) if limit is None else limit
        out: list[tuple[str, Candidate]] = []
        for i, (excluded, _, cid) in enumerate(scored):
            s = self.sensors[cid]
            if i < n_full and not excluded:
                # One plan ranks a demand's cameras more than once (the first demand, then its
                # spare cameras): each camera's best pose for it is found once per plan.
                key = (cid, demand.index, dt, joints[cid].tobytes(), demand.position.tobytes())
                cand = self._ranked.get(key) or best_achievable_pose(
                    s,
                    joints[cid],
                    demand.target,
                    dt,
                    self.model,
                    self.setup.marker_radius,
                    self.samples,
                    self.occluders(demand),
                )
                self._ranked[key] = cand
            else:
                cand = Candidate(joints[cid], 0.0, math.nan, math.nan, False)
            out.append((cid, cand))
        # Stable sort: equal visibilities keep the normalised-distance order.
        out.sort(key=lambda item: -item[1].visibility)
        return out

    # -- planning ----------------------------------------------------------------------------
    def manoeuvre(self) -> None:
        """The predictor saw the object manoeuvre: the next plan replans the first demand's
        poses as if its prediction had left the box."""
        self._manoeuvre = True

    def _replan_needed(self, frozen: _Frozen, new: Demand, alive: list[str]) -> bool:
        if self._manoeuvre:
            return True
        delta = np.abs(new.position - frozen.reference.position)
        if bool(np.any(delta > self.rho * frozen.reference.sigma())):
            return True
        for c in alive:
            cand = frozen.desired.get(c)
            if cand is None:
                continue
            if not self._view(c, cand.joints, new).in_view:
                return True
        return False

    def plan(self, now: float, demands: Sequence[Demand], joints: dict[str, Array]) -> Plan:
        """Plan for the current horizon; ``joints`` holds each camera's current positions.

        Cameras missing from ``joints`` (no stage state yet) or excluded are not dispatched.
        """
        self._horizon = list(demands)
        self._occluders = {}
        self._ranked = {}
        self._seen = {}
        cams = [c for c in self.sensors if c in joints and c not in self.excluded]
        horizon = sorted(
            (d for d in demands if d.index not in self._serviced and d.time > now),
            key=lambda d: (d.time, d.index),  # the next instant is served first
        )
        assignments: dict[str, Assignment] = {}
        replanned = False
        ranking: tuple[tuple[str, float], ...] = ()
        blurred: tuple[tuple[str, float], ...] = ()
        fused = 0.0
        first_index = horizon[0].index if horizon else -1
        free = list(cams)
        limit = min(len(cams), self.k + self.extra)
        if horizon:
            first = horizon[0]
            frozen = self._frozen.get(first.index)
            if frozen is None:
                ranked = self.rank(first, cams, joints, now, limit)
                ranking = tuple((c, cand.visibility) for c, cand in ranked)
                blurred = tuple(
                    (c, loss)
                    for c, cand in ranked
                    if cand.visibility > 0.0
                    and (
                        loss := blur_loss(
                            self.sensors[c],
                            cand.joints,
                            first.target,
                            self.setup.marker_radius,
                            self.model,
                        )
                    )
                    > 0.0
                )
                # Only cameras that can see the demand are worth freezing on it; if none can,
                # the best k still try (the demand then gets an explicit failure, not silence).
                chosen = [item for item in ranked[: self.k] if item[1].visibility > 0.0] or ranked[
                    : self.k
                ]
                frozen = _Frozen(tuple(c for c, _ in chosen), first, dict(chosen))
                self._frozen[first.index] = frozen
            else:
                alive, replanned = self._keep_frozen(frozen, first, cams, joints, now)
                ranking = tuple((c, frozen.desired[c].visibility) for c in alive)
            for c in frozen.cameras:
                if c in frozen.desired and c in free:
                    cand = frozen.desired[c]
                    assignments[c] = Assignment(
                        c, Role.ASSIGNED, first.index, cand.joints, cand.visibility
                    )
                    free.remove(c)
            if first.index not in self._closed:
                for c, q in self._standby(first, frozen, free, joints, now).items():
                    assignments[c] = Assignment(c, Role.PREASSIGNED, first.index, q, 0.0)
                    free.remove(c)
            fused = self.fused_visibility(first, {c: assignments[c].desired for c in assignments})
            # Preassignment and prepositioning of the rest, demand by demand.
            for later in horizon[1:]:
                if not free:
                    break
                ranked = self.rank(later, free, joints, now, min(len(free), limit))
                for c, cand in ranked[: self.k]:
                    assignments[c] = Assignment(
                        c, Role.PREASSIGNED, later.index, cand.joints, cand.visibility
                    )
                    free.remove(c)
        for c in free:
            assignments[c] = Assignment(c, Role.IDLE, -1, joints[c], 0.0)
        return Plan(now, first_index, assignments, fused, replanned, ranking, blurred)

    def _keep_frozen(
        self,
        frozen: _Frozen,
        first: Demand,
        cams: list[str],
        joints: dict[str, Array],
        now: float,
    ) -> tuple[list[str], bool]:
        """The first demand's frozen assignment, kept up to date: its cameras' poses replanned
        when its prediction moved (eq. 1 again), cameras whose view became blocked swapped out,
        empty slots refilled from spare cameras. Returns the cameras serving it and whether it
        was replanned."""
        replanned = False
        alive = [c for c in frozen.cameras if c in joints and c not in self.excluded]
        if self._replan_needed(frozen, first, alive):
            replanned = True
            dt = first.time - now - self.settle_time
            for c in alive:
                frozen.desired[c] = self._better(
                    c,
                    frozen.desired.get(c),
                    best_achievable_pose(
                        self.sensors[c],
                        joints[c],
                        first.target,
                        dt,
                        self.model,
                        self.setup.marker_radius,
                        self.samples,
                        self.occluders(first),
                    ),
                    first,
                )
            frozen.reference = first
            self.replans += 1
            # Ours, beyond the paper: a camera whose view of the demand something now
            # blocks leaves its assignment (until the capture request), to be replaced.
            if first.index not in self._closed:
                gone = [
                    c
                    for c in alive
                    if frozen.desired[c].visibility <= 0.0
                    and self._blocked(c, frozen.desired[c].joints, first)
                ]
                frozen.cameras = tuple(c for c in frozen.cameras if c not in gone)
                for c in gone:
                    frozen.desired.pop(c, None)
                alive = [c for c in alive if c not in gone]
                self.occlusion_swaps += len(gone)
        self._manoeuvre = False
        missing = self.k - len(alive)
        spare = [c for c in cams if c not in frozen.cameras]
        if missing > 0 and spare and first.index not in self._closed:
            ranked = self.rank(first, spare, joints, now, len(spare))
            extra = [item for item in ranked[:missing] if item[1].visibility > 0.0]
            if extra:
                frozen.cameras += tuple(c for c, _ in extra)
                frozen.desired.update(extra)
                alive += [c for c, _ in extra]
        return alive, replanned

    def _standby(
        self,
        first: Demand,
        frozen: _Frozen,
        free: list[str],
        joints: dict[str, Array],
        now: float,
    ) -> dict[str, Array]:
        """Poses for the spare cameras that make up a short first assignment.

        An assignment made early in a track (a tentative prediction, little time left) can
        freeze fewer than k cameras: the others could not see the demand from anywhere they
        could reach by then. Rather than preposition them for later demands, the best-ranked
        of them head for the first demand at once (to the best pose they can reach, or, when
        none sees it yet, towards their ideal pose for it), so that the top-up finds them able
        to see it before its capture request goes out.
        """
        missing = self.k - len([c for c in frozen.cameras if c in frozen.desired])
        spare = [c for c in free if self.sensors[c].moves]
        if missing <= 0 or not spare:
            return {}
        out: dict[str, Array] = {}
        dt = max(first.time - now - self.settle_time, 0.0)
        for c, cand in self.rank(first, spare, joints, now, len(spare))[:missing]:
            out[c] = (
                cand.joints if cand.visibility > 0.0 else self._towards(c, joints[c], first, dt)
            )
        return out

    def _towards(self, camera_id: str, q0: Array, demand: Demand, dt: float) -> Array:
        """The pose from which the camera sees ``demand``'s prediction soonest: over the
        stage's whole range, the aimed pose in view with the least travel time (rest to rest,
        the slower axis deciding); the stages move there at full speed."""
        s = self.sensors[camera_id]
        target = Target(demand.position, demand.normal, 0.0, demand.velocity)
        if s.has_linear:
            lim = s.limits[0]
            lin = np.unique(
                np.concatenate([np.linspace(lim.min_position, lim.max_position, 61), [q0[0]]])
            )
            q = np.column_stack([lin, aim_yaw(s, lin, target)])
        else:
            q = aim_yaw(s, np.zeros(1), target)[:, None]
        rot = s.limits[-1]
        q[:, -1] = np.clip(q[:, -1], rot.min_position, rot.max_position)
        vis, _, _, inside = view_batch(
            s, q, target, self.setup.marker_radius, self.model, occluders=self.occluders(demand)
        )
        if not np.any(inside):
            return q0
        times = np.array(
            [
                max(
                    min_travel_time(
                        float(qi[j] - q0[j]), lim_j.max_velocity, lim_j.max_acceleration
                    )
                    for j, lim_j in enumerate(s.limits)
                )
                for qi in q
            ]
        )
        times = np.where(inside, times, np.inf)
        best = int(np.lexsort((-vis, times))[0])
        return np.asarray(q[best], dtype=np.float64)

    def fused_visibility(self, demand: Demand, poses: dict[str, Array]) -> float:
        """v_f (eq. 2) of cameras at ``poses`` for ``demand``; out-of-view cameras add nothing."""
        return visibility_at_poses(
            self.sensors,
            self.model,
            dict(poses),
            demand.target,
            self.setup.marker_radius,
            self.occluders(demand),
            view=lambda c, q: self._view(c, q, demand),
        )
