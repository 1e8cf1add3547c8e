"""Conversions between the simulator's truth and messages."""

from __future__ import annotations

from builtin_interfaces.msg import Time

from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_sim.xytable import ObjectState


def object_state_msg(state: ObjectState, stamp: Time, frame_id: str) -> ObjectStateMsg:
    msg = ObjectStateMsg()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.top_marker.x, msg.top_marker.y, msg.top_marker.z = (float(v) for v in state.top)
    msg.side_marker.x, msg.side_marker.y, msg.side_marker.z = (float(v) for v in state.side)
    n = state.side_normal
    msg.side_normal.x, msg.side_normal.y, msg.side_normal.z = (float(v) for v in n)
    msg.velocity.x, msg.velocity.y, msg.velocity.z = (float(v) for v in state.velocity)
    msg.in_workspace = bool(state.present)
    return msg
