"""The ``imager`` node (one per camera): marker pose in the world at each demand instant.

On a capture request that names its camera it takes the frame exposed at the demand instant,
measures the marker (detection, weighted ellipse fit, circle pose, choice by the predicted
normal), moves the pose into the world with the camera pose from the stage joint states,
attaches the sensor model's covariance, and publishes a MarkerObservation. When it cannot, it
publishes the observation with a failure status and reason instead of staying silent. The
decisions are :class:`activesurv_imaging.capture.CaptureCore`'s; this node only wires topics.

Subscribes: capture_request, <camera_id>/image_raw, <camera_id>/camera_info,
    <camera_id>/stage/joint_states (unless the mount is static).
Publishes: marker_observations, <camera_id>/marker_annotations (ImageMarker: the ellipse, its
    centre and the chosen normal, or the failure) and <camera_id>/demand_frame
    (``record_frames``), both ``viewers_delay`` s after the observation
    (:mod:`activesurv_imaging.ros.viewers`), <camera_id>/imager/heartbeat (Header, 10 Hz:
    the dispatcher stops assigning a camera whose beat stops), /diagnostics.
Parameters: see ``config/imager.yaml`` (typed: :class:`activesurv_imaging.capture.ImagerConfig`).
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from activesurv_common.ros import diagnostics, local_topics, qos, topics
from activesurv_common.ros.conversions import (
    MOUNT_PARAMETERS,
    image_to_gray,
    joint_vector,
    model_from_camera_info,
    mount_from_parameters,
    sec_to_time,
    time_to_sec,
    vector3,
)
from activesurv_common.ros.fine_clock import FineClock
from activesurv_common.ros.instants import periodic
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import declare
from activesurv_imaging.capture import CaptureCore, core_from_parameters
from activesurv_imaging.conversions import info_disagreement, observation_to_msg
from activesurv_imaging.errors import VisionErrors
from activesurv_imaging.imager_params import PARAMS
from activesurv_imaging.kernels import warm_up
from activesurv_imaging.ros.software_trigger import SoftwareTrigger
from activesurv_imaging.ros.viewers import ObservationViews
from activesurv_interfaces.msg import CaptureRequest, MarkerObservation


class ImagerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('imager', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.camera_id = str(v['camera_id'])
        mount = mount_from_parameters(self.camera_id, {n: v[n] for n in MOUNT_PARAMETERS})
        self.core: CaptureCore[Image] = core_from_parameters(v, mount, image_to_gray)
        self.counts: Counter[str] = Counter()
        warm_up()  # the imaging kernels compiled (make setup) or loaded before the first frame
        self._info_tolerance = float(v['camera_info_tolerance'])
        self._info_checked = False  # a driver's camera_info only compared with the file's
        self._fine = FineClock(self.get_clock(), self)
        service = str(v['trigger_service'])
        self._trigger = SoftwareTrigger(self, service, v['trigger_lead']) if service else None
        self._obs_pub = self.create_publisher(
            MarkerObservation, topics.MARKER_OBSERVATIONS, qos.EVENTS_LATCHED
        )
        beat = topics.heartbeat(self.camera_id)
        self._beat_pub = self.create_publisher(Header, beat, qos.SENSOR)
        self._diag_pub = self.create_publisher(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        delay = float(v['viewers_delay'])  # after the estimate: the cores image till then
        self.views = ObservationViews(self, self.camera_id, bool(v['record_frames']), delay)
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS
        )
        # Drivers publish best effort; our simulated cameras and replays reliably (none lost).
        image_qos = qos.SENSOR_RELIABLE if v['reliable_images'] else qos.SENSOR
        image = topics.image(self.camera_id)  # from a camera in its container: in process
        local_topics.subscription(self, Image, image, self._on_image, image_qos)
        info = topics.camera_info(self.camera_id)
        local_topics.subscription(self, CameraInfo, info, self._on_info, qos.SENSOR)
        if self.core.joint_names:
            # Reliable with the simulator and replays: the state latched at a demand instant
            # must not be dropped in a burst (a replay then measured with another pose).
            state_qos = qos.STATE if v['reliable_images'] else qos.SENSOR
            states, cb = topics.joint_states(self.camera_id), self._on_joints  # in process
            local_topics.subscription(self, JointState, states, cb, state_qos, only_local=True)
        self.create_timer(0.05, self._on_tick)
        periodic(self, 0.1, self._beat)  # 10 Hz on the clock owner's grid, whatever /clock does
        self.create_timer(1.0, self._publish_diagnostics)

    def _now(self) -> float:  # between /clock ticks too: a frame's arrival, for the budget
        return self._fine.now()

    def _on_request(self, msg: CaptureRequest) -> None:
        if self.camera_id in msg.camera_ids:
            n, v = vector3(msg.predicted_normal), vector3(msg.predicted_velocity)
            p = vector3(msg.predicted_position)
            self.core.request(int(msg.demand_index), time_to_sec(msg.demand_instant), n, v, p)
            if self._trigger is not None:
                self._trigger.arm(int(msg.demand_index), time_to_sec(msg.demand_instant))
            self._on_tick()

    def _on_image(self, msg: Image) -> None:
        self.core.add_frame(time_to_sec(msg.header.stamp), msg, self._now())
        if self.core.pending:
            self._on_tick()  # measure as soon as the frame is here, not on the next tick

    def _on_info(self, msg: CameraInfo) -> None:
        if self.core.camera is not None:
            if not self._info_checked:
                self._info_checked = True
                self._compare_info(msg)
            return
        try:
            self.core.set_camera(model_from_camera_info(msg, self.camera_id))
            self._on_tick()
        except VisionErrors as exc:
            self.counts['bad_camera_info'] += 1
            self.get_logger().error(f'bad camera_info: {exc}', throttle_duration_sec=5)

    def _compare_info(self, msg: CameraInfo) -> None:
        """Warn once when the driver's camera_info disagrees with the commissioned one."""
        assert self.core.camera is not None
        why = info_disagreement(self.core.camera, msg, self.camera_id, self._info_tolerance)
        if why:
            self.counts['camera_info_disagrees'] += 1
            self.get_logger().warning(why)

    def _on_joints(self, msg: JointState) -> None:
        q = joint_vector(msg, self.core.joint_names)
        if q is None or not self.core.add_joints(time_to_sec(msg.header.stamp), q):
            self.counts['bad_joint_states'] += 1
        elif self.core.pending:
            self._on_tick()

    def _beat(self, t: float) -> None:
        self._beat_pub.publish(Header(stamp=sec_to_time(t), frame_id=self.camera_id))

    def _on_tick(self) -> None:
        for obs in self.core.poll(self._now()):
            self.counts[obs.status.name] += 1
            self._obs_pub.publish(observation_to_msg(obs, now=self._now()))
            found = self.core.frames.closest(obs.stamp, 1e-6) if math.isfinite(obs.stamp) else None
            image = found[1] if found is not None and self.views.records_frames else None
            self.views.publish(obs, self.core.camera, image)  # annotations, frame: later

    def flush(self) -> int:
        """The views still waiting go out (the node stops); returns how many."""
        return self.views.flush()

    def _publish_diagnostics(self) -> None:
        bad = sum(n for k, n in self.counts.items() if k != 'OK')
        values: dict[str, Any] = dict(self.counts, pending=len(self.core.pending))
        values.update(frames_buffered=len(self.core.frames))
        values['camera_info'] = self.core.camera is not None
        s = diagnostics.status(
            f'activesurv/imager/{self.camera_id}',
            self.camera_id,
            f'{sum(self.counts.values())} observations, {bad} failed',
            values,
            diagnostics.WARN if bad else diagnostics.OK,
        )
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))


def main(args: list[str] | None = None) -> int:
    return run_node('imager', ImagerNode, args, on_stop=ImagerNode.flush)


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
