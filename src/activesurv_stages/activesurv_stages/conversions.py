"""Conversions between stage messages and the stages cores."""

from __future__ import annotations

import math
from collections.abc import Sequence

from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState

from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_interfaces.msg import StageGoal
from activesurv_stages.xytable import ObjectState


def sec_to_time(t: float) -> Time:
    if not math.isfinite(t) or t < 0.0:
        return Time()
    sec = math.floor(t)
    return Time(sec=sec, nanosec=min(round((t - sec) * 1e9), 999_999_999))


def goal_items(msg: StageGoal) -> list[tuple[str, float, float | None]]:
    """(joint, position, velocity limit or None) for each joint of a goal.

    Missing or zero velocities mean the axis maximum; NaN, inf or negative velocities are
    passed on so that the axis refuses them with a reason. A goal whose arrays disagree in
    length yields no items for the unmatched joints.
    """
    out = []
    for i, name in enumerate(msg.joint_names):
        if i >= len(msg.positions):
            break
        v = msg.max_velocities[i] if i < len(msg.max_velocities) else 0.0
        out.append((str(name), float(msg.positions[i]), None if v == 0.0 else float(v)))
    return out


def joint_state(
    names: Sequence[str], positions: Sequence[float], velocities: Sequence[float], stamp: Time
) -> JointState:
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(names)
    msg.position = [float(p) for p in positions]
    msg.velocity = [float(v) for v in velocities]
    return msg


def object_state_msg(state: ObjectState, stamp: Time, frame_id: str) -> ObjectStateMsg:
    msg = ObjectStateMsg()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.top_marker.x, msg.top_marker.y, msg.top_marker.z = (float(v) for v in state.top)
    msg.side_marker.x, msg.side_marker.y, msg.side_marker.z = (float(v) for v in state.side)
    n = state.side_normal
    msg.side_normal.x, msg.side_normal.y, msg.side_normal.z = (float(v) for v in n)
    msg.velocity.x, msg.velocity.y, msg.velocity.z = (float(v) for v in state.velocity)
    msg.in_workspace = True
    return msg
