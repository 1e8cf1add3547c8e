"""Conversions between stage messages and the stages cores."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from sensor_msgs.msg import JointState

from activesurv_common.ros.conversions import time_to_sec
from activesurv_interfaces.msg import StageGoal
from activesurv_stages.bridge import LinkState, Snapshot
from activesurv_stages.config import ControllerConfig

GOAL_MAX_AGE = 60.0
"""s: a goal stamped further than this from the stage's own clock is not followed."""


def stale_goal(msg: StageGoal, now: float, max_age: float = GOAL_MAX_AGE) -> str | None:
    """Why a goal must not move the stage, or None.

    Goals are latched (transient local): a stage that starts hears the last goal of every
    publisher still alive on its domain, including one of another run (a finished
    commissioning, a session on the wall clock while this run keeps simulated time). A goal
    stamped more than ``max_age`` seconds from the stage's clock (before or after) belongs
    to no plan of this run and is refused. An unstamped goal (zero stamp: sent by hand) is
    followed.
    """
    stamp = time_to_sec(msg.header.stamp)
    if stamp == 0.0 or abs(now - stamp) <= max_age:
        return None
    return (
        f"goal stamped {stamp:.3f} s, {now - stamp:+.3f} s from this stage's clock "
        f'(more than {max_age:g} s: a latched goal of another run or clock): ignored'
    )


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


def bridge_status(
    camera_id: str,
    cfg: ControllerConfig,
    snap: Snapshot,
    estop: bool,
    extra: Mapping[str, Any],
) -> DiagnosticStatus:
    """A bridge's diagnostic status: link state, axes, counters, e-stop and ``extra`` keys."""
    s = DiagnosticStatus(
        name=f'activesurv/stage_bridge/{camera_id}', hardware_id=f'{cfg.protocol}:{cfg.port}'
    )
    s.level = {
        LinkState.READY: DiagnosticStatus.OK,
        LinkState.HOMING: DiagnosticStatus.WARN,
        LinkState.DISCONNECTED: DiagnosticStatus.ERROR,
    }[snap.state]
    if any(v == 'fault' for v in snap.statuses.values()):
        s.level = DiagnosticStatus.ERROR
    s.message = snap.state.value + (f': {snap.last_error}' if snap.last_error else '')
    if estop:
        s.level = DiagnosticStatus.ERROR
        s.message = 'e-stop raised: goals refused; ' + s.message
    s.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(snap.counters.items())]
    s.values += [KeyValue(key=f'status/{j}', value=v) for j, v in sorted(snap.statuses.items())]
    s.values += [KeyValue(key=k, value=str(v)) for k, v in extra.items()]
    return s
