"""The ``sim_camera`` node: a simulated camera that renders real pixels of the object.

Subscribes:
    object_state (activesurv_interfaces/ObjectState): the object's ground truth (xy table); with
        ``instant_states``, sim/instant_object_state: its states around requested instants.
    <camera_id>/stage/joint_states (sensor_msgs/JointState): its stage, unless static.
    capture_request (activesurv_interfaces/CaptureRequest): triggers a frame exposed exactly at
        the demand instant (like a hardware trigger armed ahead of time).
    sim/planned_object_state, sim/<camera_id>/planned_joint_states: the truth at a requested
        instant as planned; the frame is rendered ahead with it and goes out at the instant
        on the camera's own trigger (``own_trigger``) if the stage's state of the instant is
        the one it was rendered with, else once they match (``activesurv_sim.sim_camera``).
Publishes: <camera_id>/image_raw (sensor_msgs/Image, mono8) and <camera_id>/camera_info; a
    demand frame its imager took in process goes over DDS ``remote_delay`` s later.
Parameters: see ``config/sim_camera.yaml``; the mount parameters place the camera.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, JointState

from activesurv_common.errors import CommonError
from activesurv_common.pacing import Pacer, PhaseLock
from activesurv_common.ros import local_topics, qos, topics
from activesurv_common.ros.conversions import (
    MOUNT_PARAMETERS,
    declare_mount_parameters,
    gray_to_image,
    joint_vector,
    mount_from_parameters,
    object_state_vector,
    sec_to_time,
    time_to_sec,
)
from activesurv_common.ros.deferred import Deferred
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import declare
from activesurv_interfaces.msg import CaptureRequest, ObjectState
from activesurv_sim.conversions import object_topic, published_model, simulated_camera
from activesurv_sim.errors import SimError
from activesurv_sim.ros.ahead import AheadFrames
from activesurv_sim.ros.frame_messages import FrameMessages
from activesurv_sim.sim_camera_params import PARAMS
from activesurv_sim.xytable import TABLE_ID, TABLE_JOINTS


class SimCameraNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('sim_camera', **kwargs)
        declare(self, PARAMS)
        declare_mount_parameters(self)
        g = self.get_parameter
        p = {name: g(name).value for name in MOUNT_PARAMETERS}
        v = {q.name: g(q.name).value for q in PARAMS}
        self.camera_id = str(g('camera_id').value)
        self.sim = simulated_camera(v, mount_from_parameters(self.camera_id, p))
        self.sim.warm_up()
        self.frame_id = f'{self.camera_id}_optical_frame'  # REP 103, on /tf (frames node)
        model = published_model(v, self.sim)
        self.messages = FrameMessages(model, self.frame_id)
        # Its imager in the same container images a frame before the frame goes over DDS.
        image = topics.image(self.camera_id)
        self._image_pub = local_topics.publisher(self, Image, image, qos.SENSOR_RELIABLE)
        info = topics.camera_info(self.camera_id)
        self._info_pub = local_topics.publisher(self, CameraInfo, info, qos.SENSOR_RELIABLE)
        self.later = Deferred(self, float(g('remote_delay').value))  # after the estimate
        if str(g('payload').value) == 'board':  # commissioning: the table's stage carries it
            table = topics.joint_states(TABLE_ID)
            self.create_subscription(JointState, table, self._on_table, qos.STATE)
        else:  # every state, or those around its instants (reliable then: each one counts)
            topic = object_topic(v)
            profile = qos.SENSOR if topic == topics.OBJECT_STATE else qos.EVENTS
            self.create_subscription(ObjectState, topic, self._on_object, profile)
        if self.sim.joint_names:
            states, cb = topics.joint_states(self.camera_id), self._on_joints  # in process
            local_topics.subscription(self, JointState, states, cb, qos.SENSOR, only_local=True)
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS
        )
        self._pending: set[float] = set()
        self._ahead: AheadFrames | None = None
        if bool(g('render_ahead').value):
            send, own = partial(self._send, ahead=True), bool(g('own_trigger').value)
            args = (self, self.sim, self.camera_id, self._pending, send, own, self._delay)
            self._ahead = AheadFrames(*args, prepare=self.messages.prepare)
        # States arriving trigger the frames waiting for them; the timer only ends the wait.
        self.create_timer(0.05, self._on_tick)
        rate, preview = float(g('frame_rate').value), float(g('preview_rate').value)
        # States pace the streams (a busy process's timer drops ticks), see _on_state.
        self._stream = PhaseLock(rate, float(g('frame_phase').value)) if rate > 0.0 else None
        self._preview = Pacer(preview) if preview > 0.0 else None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        if preview > 0.0:
            self._preview_pub = self.create_publisher(
                Image, topics.preview(self.camera_id), qos.SENSOR_RELIABLE
            )
        self.frames_published = self.frames_ahead = self.released_differing = 0
        self._frozen: Any = None

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _delay(self) -> float:
        return float(self.get_parameter('trigger_delay').value)

    def _on_object(self, msg: ObjectState) -> None:
        t = time_to_sec(msg.header.stamp)
        if not self.sim.add_object(t, object_state_vector(msg), int(msg.slot)):
            self.get_logger().warning('ignored a non-finite object state', throttle_duration_sec=5)
            return
        if self.sim.released_differs(t):
            self.released_differing += 1
            self.get_logger().error(f'the frame of t={t:.3f} showed a state the table left')
        self._on_state(t)

    def _on_table(self, msg: JointState) -> None:
        xy = joint_vector(msg, TABLE_JOINTS)
        t = time_to_sec(msg.header.stamp)
        if xy is not None and self.sim.objects.add(t, np.r_[xy, [0.0] * 7]):
            self._on_state(t)

    def _on_joints(self, msg: JointState) -> None:
        q = joint_vector(msg, self.sim.joint_names)
        if q is None or not self.sim.joints.add(time_to_sec(msg.header.stamp), q):
            why = f'ignored joint state without finite {self.sim.joint_names}'
            self.get_logger().warning(why, throttle_duration_sec=5)
        elif self._pending:
            self._on_tick()

    def _on_request(self, msg: CaptureRequest) -> None:
        if self.camera_id in msg.camera_ids:
            t = time_to_sec(msg.demand_instant)
            self._pending.add(t)
            self._on_tick()
            if self._ahead is not None:
                self._ahead.render(t)  # the truth may be planned already

    def _publish(self, t: float, preview: bool = False) -> None:
        hold = float(self.get_parameter('state_hold').value)
        try:  # a preview leaves the frames rendered ahead for the demands alone
            gray, ahead = (
                (self.sim.render_at(t, hold), False) if preview else self.sim.frame_at(t, hold)
            )
        except (SimError, CommonError) as exc:
            self.get_logger().warning(f'no frame at t={t:.3f}: {exc}', throttle_duration_sec=2)
            return
        self._send(t, gray, ahead, preview)

    def _send(self, t: float, gray: Any, ahead: bool, preview: bool = False) -> None:
        stamp = sec_to_time(t)
        if bool(self.get_parameter('inject_frozen').value):
            if self._frozen is None:
                self._frozen = gray
            gray = self._frozen  # a stuck camera: the same pixels, fresh stamps
        if preview:  # for viewers: no camera_info, no imaging
            self._preview_pub.publish(gray_to_image(gray, self.frame_id, stamp))
            return
        # The intrinsics first: a consumer in the container then has them for the frame, and
        # its imager images the frame before either goes over DDS.
        info, image = self.messages(t, gray)  # built as the frame was rendered ahead
        pubs = (self._info_pub, info), (self._image_pub, image)
        local_topics.publish_together(*pubs, later=self.later if ahead else None)
        self.frames_published += 1
        self.frames_ahead += int(ahead)

    def flush(self) -> int:
        return self.later.flush()  # at stop: the DDS copies still waiting (how many)

    def _on_tick(self) -> None:
        g = self.get_parameter
        delay, hold = float(g('trigger_delay').value), float(g('state_hold').value)
        for t in self.sim.due(self._pending, self._now(), delay, hold):
            self._pending.discard(t)
            self._publish(t)

    def _on_state(self, t: float) -> None:
        """A new object (or table) state: the frames waiting for it, and the streams."""
        if self._pending:
            self._on_tick()  # rendered now, not on the next tick
        newest = t >= (self.sim.objects.latest_time or t)
        if self._stream is not None and newest and self._stream.ready(t):
            self._publish(t)
        wall = self._steady.now().nanoseconds * 1e-9
        if self._preview is not None and self._preview.ready(wall):
            self._publish(t, preview=True)  # wall time: for viewers


def main(args: list[str] | None = None) -> int:
    errors = (SimError, CommonError)
    return run_node('sim_camera', SimCameraNode, args, SimCameraNode.flush, errors)


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
