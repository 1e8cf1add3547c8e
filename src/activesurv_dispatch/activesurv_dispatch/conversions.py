"""Conversions between dispatcher messages and the dispatch cores."""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Point, Pose
from numpy.typing import NDArray
from visualization_msgs.msg import Marker, MarkerArray

from activesurv_common.geometry import Transform
from activesurv_common.occlusion import Box
from activesurv_common.ros.conversions import pose_from_transform, sec_to_time, time_to_sec
from activesurv_dispatch.motion import Capture, StageCommand
from activesurv_dispatch.planner import Demand, Plan, Role
from activesurv_dispatch.sensors import Sensor, Setup
from activesurv_interfaces.msg import (
    CaptureRequest,
    DemandHorizon,
    DispatchPlan,
    SensorAssignment,
    StageGoal,
)

BRIDGE_STATUS = 'activesurv/stage_bridge/'  # what each stage bridge's diagnostics are named


def _level(level: bytes | int) -> int:
    """A diagnostic level as a number (rclpy gives a byte)."""
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def stage_faults(msg: DiagnosticArray, namespace: str) -> dict[str, str]:
    """The stage bridges of this rig (``namespace``) in ``msg``: camera id -> its fault ('' when
    it reports no error)."""
    out: dict[str, str] = {}
    for status in msg.status:
        if not status.name.startswith(BRIDGE_STATUS):
            continue
        values = {kv.key: kv.value for kv in status.values}
        if values.get('namespace', '/').strip('/') != namespace.strip('/'):
            continue
        faulted = _level(status.level) >= _level(DiagnosticStatus.ERROR)
        out[status.name[len(BRIDGE_STATUS) :]] = status.message if faulted else ''
    return out


def horizon_to_demands(msg: DemandHorizon) -> list[Demand]:
    """The demands of a horizon; demands with non-finite values are left out."""
    out = []
    for d in msg.demands:
        p = d.pose.pose.position
        pos = np.array([p.x, p.y, p.z], dtype=np.float64)
        n = np.array([d.normal.x, d.normal.y, d.normal.z], dtype=np.float64)
        cov = np.array(d.pose.covariance, dtype=np.float64).reshape(6, 6)
        norm = float(np.linalg.norm(n))
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(cov)) and norm > 1e-9):
            continue
        vel = np.array([d.velocity.x, d.velocity.y, d.velocity.z], dtype=np.float64)
        out.append(
            Demand(
                int(d.index),
                time_to_sec(d.demand_instant),
                pos,
                n / norm,
                cov,
                int(d.object_id),
                vel if np.all(np.isfinite(vel)) else None,
            )
        )
    return out


class _CameraPoses:
    """The camera pose of each camera's desired joints, kept for the last few: a plan goes out
    at every overhead fix and mostly repeats the last one's poses (a kept transform also keeps
    its quaternion, :meth:`Transform.quaternion`)."""

    def __init__(self, size: int = 64) -> None:
        self._size = size
        # (id of the mount, joints) -> (the mount itself, its camera pose there): the mount is
        # held, so its id cannot pass to another while kept.
        self._kept: dict[tuple[int, tuple[float, ...]], tuple[object, Transform]] = {}

    def __call__(self, sensor: Sensor, q: NDArray[np.float64]) -> Pose:
        key = (id(sensor.mount), tuple(float(v) for v in q))
        kept = self._kept.get(key)
        if kept is None or kept[0] is not sensor.mount:
            if len(self._kept) >= self._size:
                self._kept.pop(next(iter(self._kept)))
            kept = self._kept[key] = (sensor.mount, sensor.mount.pose_from_joints(q))
        return pose_from_transform(kept[1])


_camera_pose = _CameraPoses()


def plan_to_msg(plan: Plan, setup: Setup, replans: int, frame_id: str) -> DispatchPlan:
    msg = DispatchPlan()
    msg.header.stamp = sec_to_time(plan.stamp)
    msg.header.frame_id = frame_id
    msg.first_demand_index = max(plan.first_index, 0)
    msg.expected_fused_visibility = float(plan.fused_visibility)
    msg.replan_count = int(replans)
    for s in setup.sensors:
        a = plan.assignments.get(s.camera_id)
        if a is None:
            continue
        sa = SensorAssignment(
            camera_id=s.camera_id, role=int(a.role.value), demand_index=max(a.demand_index, 0)
        )
        sa.joint_names = list(s.joint_names)
        sa.desired_positions = [float(v) for v in a.desired]
        sa.desired_camera_pose = _camera_pose(s, a.desired)
        sa.expected_visibility = float(a.visibility)
        msg.assignments.append(sa)
    return msg


def command_to_goal(cmd: StageCommand, stamp: float) -> StageGoal:
    msg = StageGoal()
    msg.header.stamp = sec_to_time(stamp)
    msg.joint_names = list(cmd.joint_names)
    msg.positions = [float(v) for v in cmd.positions]
    msg.max_velocities = [float(v) for v in cmd.max_velocities]
    msg.arrival_time = sec_to_time(cmd.arrival_time)
    return msg


def capture_to_request(capture: Capture, stamp: float, frame_id: str) -> CaptureRequest:
    msg = CaptureRequest()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.demand_index = int(capture.demand.index)
    msg.demand_instant = sec_to_time(capture.demand.time)
    msg.camera_ids = list(capture.cameras)
    p, n = capture.demand.position, capture.demand.normal
    msg.predicted_position.x, msg.predicted_position.y, msg.predicted_position.z = (
        float(v) for v in p
    )
    msg.predicted_normal.x, msg.predicted_normal.y, msg.predicted_normal.z = (float(v) for v in n)
    v = capture.demand.velocity
    if v is not None:
        vel = msg.predicted_velocity
        vel.x, vel.y, vel.z = (float(x) for x in v)
    return msg


_COLOURS = {
    Role.ASSIGNED: (0.1, 0.8, 0.1),
    Role.PREASSIGNED: (0.9, 0.7, 0.1),
    Role.IDLE: (0.5, 0.5, 0.5),
}


def plan_markers(
    plan: Plan, setup: Setup, joints: dict[str, np.ndarray], demands: list[Demand], frame_id: str
) -> MarkerArray:
    """Cameras (arrows, coloured by role), lines to their demands, and the demand points."""
    arr = MarkerArray()
    stamp = sec_to_time(plan.stamp)
    arr.markers.append(Marker(action=Marker.DELETEALL))
    mid = 0
    by_index = {d.index: d for d in demands}
    for s in setup.sensors:
        q = joints.get(s.camera_id)
        a = plan.assignments.get(s.camera_id)
        if q is None or a is None:
            continue
        T = s.mount.pose_from_joints(q)
        r, g, b = _COLOURS[a.role]
        m = Marker(ns='cameras', id=mid, type=Marker.ARROW, action=Marker.ADD)
        mid += 1
        m.header.frame_id, m.header.stamp = frame_id, stamp
        tip = T.t + 0.08 * T.R[:, 2]
        m.points = [
            Point(x=float(T.t[0]), y=float(T.t[1]), z=float(T.t[2])),
            Point(x=float(tip[0]), y=float(tip[1]), z=float(tip[2])),
        ]
        m.scale.x, m.scale.y, m.scale.z = 0.008, 0.016, 0.02
        m.color.r, m.color.g, m.color.b, m.color.a = r, g, b, 1.0
        arr.markers.append(m)
        d = by_index.get(a.demand_index)
        if d is not None and a.role is not Role.IDLE:
            line = Marker(ns='assignments', id=mid, type=Marker.LINE_LIST, action=Marker.ADD)
            mid += 1
            line.header.frame_id, line.header.stamp = frame_id, stamp
            line.points = [
                Point(x=float(T.t[0]), y=float(T.t[1]), z=float(T.t[2])),
                Point(x=float(d.position[0]), y=float(d.position[1]), z=float(d.position[2])),
            ]
            line.scale.x = 0.002
            line.color.r, line.color.g, line.color.b, line.color.a = r, g, b, 0.6
            arr.markers.append(line)
    for d in demands:
        m = Marker(ns='demands', id=mid, type=Marker.SPHERE, action=Marker.ADD)
        mid += 1
        m.header.frame_id, m.header.stamp = frame_id, stamp
        m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in d.position)
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = 0.01
        first = d.index == plan.first_index
        m.color.r, m.color.g, m.color.b, m.color.a = (
            (1.0, 0.2, 0.2, 1.0) if first else (0.3, 0.5, 1.0, 0.7)
        )
        arr.markers.append(m)
    for o in setup.obstacles:  # the cell's fixtures, grey
        kind = Marker.CUBE if isinstance(o, Box) else Marker.CYLINDER
        m = Marker(ns='obstacles', id=mid, type=kind, action=Marker.ADD)
        mid += 1
        m.header.frame_id, m.header.stamp = frame_id, stamp
        m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in o.centre)
        m.pose.orientation.w = 1.0
        if isinstance(o, Box):
            m.scale.x, m.scale.y, m.scale.z = (float(v) for v in o.size)
        else:
            m.scale.x = m.scale.y = 2.0 * o.radius
            m.scale.z = o.height
        m.color.r = m.color.g = m.color.b = 0.55
        m.color.a = 0.9
        arr.markers.append(m)
    return arr


def plan_view_key(plan: Plan) -> tuple[object, ...]:
    """What a plan's markers show in kind (the demand served, each camera's role and demand): a
    change goes to viewers at once, moves at the markers' period (``ViewThrottle``)."""
    roles = tuple((c, a.role, a.demand_index) for c, a in sorted(plan.assignments.items()))
    return (plan.first_index, roles)
