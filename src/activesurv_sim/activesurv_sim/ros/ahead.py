"""A simulated camera's frames rendered ahead, and sent at their instant on its own trigger.

The xy table and the camera's stage publish the truth of a requested instant as soon as it is
determined (``sim/planned_object_state``, ``sim/<camera_id>/planned_joint_states``); the
camera renders the instant's frame then (:meth:`SimulatedCamera.render_ahead`). With
``own_trigger`` the frame goes out at the instant itself, on a steady timer at the clock
owner's mapping (:class:`~activesurv_common.ros.instants.InstantTimers`), as a triggered
camera exposes on its own clock: it waits neither for the table's state of the instant (a hop
through another process) nor for ``/clock``. It goes out only if the stage's state stamped
with the instant is still the one it was rendered with (every new goal replaces it); otherwise,
and without the mapping, it waits for the states of the instant as before.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from rclpy.node import Node
from sensor_msgs.msg import JointState

from activesurv_common.errors import CommonError
from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import joint_vector, object_state_vector, time_to_sec
from activesurv_common.ros.instants import InstantTimers
from activesurv_interfaces.msg import ObjectState
from activesurv_sim.errors import SimError
from activesurv_sim.sim_camera import SimulatedCamera

Send = Callable[[float, NDArray[np.uint8]], None]


class AheadFrames:
    """The planned truth of ``pending`` instants taken, their frames rendered ahead and (with
    ``own_trigger``) sent at ``instant + delay()`` through ``send(t, frame)``; ``prepare(t,
    frame)``, if given, is handed each frame as it is rendered (its messages built ahead)."""

    def __init__(
        self,
        node: Node,
        sim: SimulatedCamera,
        camera_id: str,
        pending: set[float],
        send: Send,
        own_trigger: bool,
        delay: Callable[[], float],
        prepare: Callable[[float, NDArray[np.uint8]], None] | None = None,
    ) -> None:
        self._node, self._sim, self._pending, self._send = node, sim, pending, send
        self._delay, self._prepare = delay, prepare
        self._trigger = InstantTimers(node) if own_trigger else None
        node.create_subscription(
            ObjectState, topics.PLANNED_OBJECT_STATE, self._on_planned_object, qos.EVENTS
        )
        if sim.joint_names:
            planned = topics.planned_joint_states(camera_id)
            node.create_subscription(JointState, planned, self._on_planned_joints, qos.EVENTS)

    def _on_planned_object(self, msg: ObjectState) -> None:
        t, v = time_to_sec(msg.header.stamp), msg.velocity
        self._sim.plan(t, object_state_vector(msg), None, int(msg.slot), [v.x, v.y, v.z])
        self.render(t)

    def _on_planned_joints(self, msg: JointState) -> None:
        names, t = self._sim.joint_names, time_to_sec(msg.header.stamp)
        q = joint_vector(msg, names)
        if q is not None:
            self._sim.plan(t, q=q, q_rate=joint_vector(msg, names, 'velocity'))
            self.render(t)

    def render(self, t: float) -> None:
        """Render the frame of ``t`` now if it is requested and its truth planned; then arm
        the camera's own trigger for it."""
        if t not in self._pending:
            return
        try:
            ready = self._sim.render_ahead(t)
        except (SimError, CommonError) as exc:
            self._node.get_logger().warning(f'no frame ahead for t={t:.3f}: {exc}')
            return
        frame = self._sim.ahead_frame(t) if ready else None
        if frame is not None and self._prepare is not None:
            self._prepare(t, frame)  # its messages too, off the instant's critical path
        if ready and self._trigger is not None:
            self._trigger.at(t + self._delay(), lambda: self._release(t))

    def _release(self, t: float) -> None:
        if t in self._pending and (frame := self._sim.release(t)) is not None:
            self._pending.discard(t)
            self._send(t, frame)
