"""Conversions between stage messages and the stages cores."""

from __future__ import annotations

from collections.abc import Sequence

from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState

from activesurv_interfaces.msg import StageGoal


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
