"""The table's truth as messages: the object states a simulated xy table (and a hardware run's
table runner) publishes. Apart from :mod:`activesurv_sim.conversions`, whose simulated cameras
load the renderer and numba: the table's process started 0.45 s of CPU lighter so."""

from __future__ import annotations

from builtin_interfaces.msg import Time

from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_sim.stream import ObjectStream
from activesurv_sim.xytable import ObjectState, XYTable


def object_state_msg(
    state: ObjectState, stamp: Time, frame_id: str, object_id: int = 1, slot: int = 0
) -> ObjectStateMsg:
    msg = ObjectStateMsg()
    msg.id = int(object_id) if state.present else 0
    msg.slot = int(slot)
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.top_marker.x, msg.top_marker.y, msg.top_marker.z = (float(v) for v in state.top)
    msg.side_marker.x, msg.side_marker.y, msg.side_marker.z = (float(v) for v in state.side)
    n = state.side_normal
    msg.side_normal.x, msg.side_normal.y, msg.side_normal.z = (float(v) for v in n)
    msg.velocity.x, msg.velocity.y, msg.velocity.z = (float(v) for v in state.velocity)
    msg.in_workspace = bool(state.present)
    return msg


def table_states(table: XYTable | ObjectStream, t: float) -> list[tuple[int, int, ObjectState]]:
    """(object id, lane, state) of the table at ``t``: one state, or one per lane with several
    objects at once (id 0: nobody in that lane; an experiment's object is 1)."""
    if isinstance(table, ObjectStream) and table.at_once > 1:
        out = []
        for k in range(table.at_once):
            oid, state = table.slot_state(k, t)
            out.append((oid, k, state))
        return out
    if isinstance(table, ObjectStream):
        p = table.pass_at(t)
        return [(p.id if p is not None else 0, 0, table.state(t))]
    return [(1, 0, table.state(t))]
