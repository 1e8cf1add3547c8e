"""The ``imager`` node (one per camera): marker pose in the world at each demand instant.

On a capture request that names its camera it takes the frame exposed at the demand instant,
measures the marker (detection, weighted ellipse fit, circle pose, choice by the predicted
normal), moves the pose into the world with the camera pose from the stage joint states,
attaches the sensor model's covariance, and publishes a MarkerObservation. When it cannot, it
publishes the observation with a failure status and reason instead of staying silent.

Subscribes: capture_request, <camera_id>/image_raw, <camera_id>/camera_info,
    <camera_id>/stage/joint_states (unless the mount is static).
Publishes: marker_observations, <camera_id>/imager/heartbeat (std_msgs/Header at 10 Hz of the
    node clock: the dispatcher stops assigning this camera when the beat stops), /diagnostics.
"""

from __future__ import annotations

import math
import sys
import zlib
from collections import Counter
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from activesurv_imaging import qos, topics
from activesurv_imaging.camera_model import CameraModel
from activesurv_imaging.conversions import (
    MOUNT_PARAMETERS,
    declare_mount_parameters,
    image_to_gray,
    joint_vector,
    model_from_camera_info,
    mount_from_parameters,
    observation_to_msg,
    time_to_sec,
)
from activesurv_imaging.errors import ImagingError
from activesurv_imaging.geometry import Transform
from activesurv_imaging.mount import CameraMount
from activesurv_imaging.observation import (
    Observation,
    ObservationStatus,
    failed,
    observe_marker,
    perturb,
)
from activesurv_imaging.sensor_model import SensorModel
from activesurv_imaging.timeseries import FrameBuffer, TimeSeries
from activesurv_interfaces.msg import CaptureRequest, MarkerObservation

POSITIVE = ('marker_radius', 'frame_tolerance', 'frame_timeout', 'joint_hold')


@dataclass
class Pending:
    index: int
    demand_time: float
    prior_normal: np.ndarray


class ImagerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('imager', **kwargs)
        d = ParameterDescriptor
        self.declare_parameter('camera_id', 'cam1', d(description='camera this imager serves'))
        self.declare_parameter('marker_radius', 0.0125, d(description='side marker radius (m)'))
        self.declare_parameter(
            'sensor_model_file', '', d(description='sensor model YAML; empty: the packaged model')
        )
        self.declare_parameter(
            'frame_tolerance', 0.005, d(description='max |frame stamp - demand instant| (s)')
        )
        self.declare_parameter(
            'frame_timeout', 1.0, d(description='s after the demand instant to wait for a frame')
        )
        self.declare_parameter(
            'joint_hold', 0.2, d(description='s a stage state may be held beyond its stamp')
        )
        self.declare_parameter(
            'reliable_images',
            False,
            d(description='subscribe to images reliably (publisher must be)'),
        )
        self.declare_parameter('inject_bias_x', 0.0, d(description='fault: m added to world x'))
        self.declare_parameter('inject_noise', 0.0, d(description='fault: extra position std'))
        self.declare_parameter('inject_flip', False, d(description='fault: wrong circle pose'))
        declare_mount_parameters(self)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')

        self.camera_id = str(self.get_parameter('camera_id').value)
        self.mount: CameraMount | Transform = mount_from_parameters(
            self.camera_id, {n: self.get_parameter(n).value for n in MOUNT_PARAMETERS}
        )
        path = str(self.get_parameter('sensor_model_file').value)
        self.model = SensorModel.load(path or None)
        self.camera: CameraModel | None = None
        self.frames: FrameBuffer[Image] = FrameBuffer(60)
        names = self.mount.joint_names if isinstance(self.mount, CameraMount) else ()
        self.joint_names = names
        self.joints = TimeSeries(max(len(names), 1))
        self.pending: list[Pending] = []
        self.counts: Counter[str] = Counter()
        self._rng = np.random.default_rng(zlib.crc32(self.camera_id.encode()))  # stable seed

        self._obs_pub = self.create_publisher(
            MarkerObservation, topics.MARKER_OBSERVATIONS, qos.EVENTS_LATCHED
        )
        self._diag_pub = self.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS
        )
        # Real camera drivers publish best effort; our simulated cameras (and replays) publish
        # reliably, and then nothing needs to be lost.
        image_qos = (
            qos.SENSOR_RELIABLE
            if bool(self.get_parameter('reliable_images').value)
            else qos.SENSOR
        )
        self.create_subscription(Image, topics.image(self.camera_id), self._on_image, image_qos)
        self.create_subscription(
            CameraInfo, topics.camera_info(self.camera_id), self._on_info, qos.SENSOR
        )
        if names:
            self.create_subscription(
                JointState, topics.joint_states(self.camera_id), self._on_joints, qos.SENSOR
            )
        self._beat_pub = self.create_publisher(
            Header, topics.heartbeat(self.camera_id), qos.SENSOR
        )
        self.create_timer(0.05, self._on_tick)
        self.create_timer(0.1, self._beat)
        self.create_timer(1.0, self._publish_diagnostics)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name in POSITIVE and (
                not isinstance(p.value, float) or not math.isfinite(p.value) or p.value <= 0.0
            ):
                return SetParametersResult(
                    successful=False, reason=f'{p.name} must be a finite float > 0'
                )
        return SetParametersResult(successful=True)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # -- inputs ------------------------------------------------------------------------------
    def _on_request(self, msg: CaptureRequest) -> None:
        if self.camera_id not in msg.camera_ids:
            return
        n = msg.predicted_normal
        self.pending.append(
            Pending(
                int(msg.demand_index),
                time_to_sec(msg.demand_instant),
                np.array([n.x, n.y, n.z], dtype=np.float64),
            )
        )

    def _on_image(self, msg: Image) -> None:
        self.frames.add(time_to_sec(msg.header.stamp), msg)

    def _on_info(self, msg: CameraInfo) -> None:
        if self.camera is None:
            try:
                self.camera = model_from_camera_info(msg, self.camera_id)
            except ImagingError as exc:
                self.get_logger().error(f'bad camera_info: {exc}', throttle_duration_sec=5)

    def _on_joints(self, msg: JointState) -> None:
        q = joint_vector(msg, self.joint_names)
        if q is None or not self.joints.add(time_to_sec(msg.header.stamp), q):
            self.get_logger().warning(
                f'ignored joint state without finite {self.joint_names}', throttle_duration_sec=5
            )

    # -- the work ----------------------------------------------------------------------------
    def _camera_pose(self, t: float) -> Transform | None:
        if not isinstance(self.mount, CameraMount):
            return self.mount
        q = self.joints.at(t, float(self.get_parameter('joint_hold').value))
        if q is None:
            return None
        if self.mount.linear_axis is None:
            return self.mount.camera_pose(0.0, float(q[0]))
        return self.mount.camera_pose(float(q[0]), float(q[1]))

    def _try(self, p: Pending, now: float) -> Observation | None:
        """The observation for ``p``, or None to keep waiting."""
        timed_out = now > p.demand_time + float(self.get_parameter('frame_timeout').value)
        hit = self.frames.closest(
            p.demand_time, float(self.get_parameter('frame_tolerance').value)
        )
        if hit is None:
            if timed_out:
                return failed(
                    self.camera_id,
                    p.index,
                    p.demand_time,
                    ObservationStatus.NO_IMAGE,
                    f'no frame within {self.get_parameter("frame_tolerance").value} s '
                    f'of the demand instant {p.demand_time:.3f} s',
                )
            return None
        stamp, frame = hit
        if self.camera is None:
            if timed_out:
                return failed(
                    self.camera_id,
                    p.index,
                    stamp,
                    ObservationStatus.NO_IMAGE,
                    'no camera_info received: intrinsics unknown',
                )
            return None
        latest = self.joints.latest_time
        if (
            isinstance(self.mount, CameraMount)
            and not timed_out
            and (latest is None or latest < stamp)
        ):
            return None  # wait for a stage state at or after the frame: interpolate, not hold
        T = self._camera_pose(stamp)
        if T is None:
            if timed_out or (latest is not None and latest > stamp + 1.0):
                return failed(
                    self.camera_id,
                    p.index,
                    stamp,
                    ObservationStatus.NO_CAMERA_POSE,
                    f'no stage state for {self.joint_names} at {stamp:.3f} s',
                )
            return None
        try:
            gray = image_to_gray(frame)
        except ImagingError as exc:
            return failed(self.camera_id, p.index, stamp, ObservationStatus.REJECTED, str(exc), T)
        prior = p.prior_normal if np.all(np.isfinite(p.prior_normal)) else None
        g = self.get_parameter
        obs = observe_marker(
            gray,
            self.camera,
            T,
            float(g('marker_radius').value),
            self.model,
            self.camera_id,
            p.index,
            stamp,
            prior,
            bool(g('inject_flip').value),
        )
        return perturb(
            obs, float(g('inject_bias_x').value), float(g('inject_noise').value), self._rng
        )

    def _beat(self) -> None:
        self._beat_pub.publish(
            Header(stamp=self.get_clock().now().to_msg(), frame_id=self.camera_id)
        )

    def _on_tick(self) -> None:
        now = self._now()
        keep = []
        for p in self.pending:
            obs = self._try(p, now)
            if obs is None:
                keep.append(p)
                continue
            self.counts[obs.status.name] += 1
            self._obs_pub.publish(observation_to_msg(obs))
            if obs.status is not ObservationStatus.OK:
                self.get_logger().warning(f'demand {p.index}: {obs.status.name}: {obs.reason}')
        self.pending = keep

    def _publish_diagnostics(self) -> None:
        s = DiagnosticStatus(
            name=f'activesurv/imager/{self.camera_id}', hardware_id=self.camera_id
        )
        bad = sum(v for k, v in self.counts.items() if k != 'OK')
        s.level = DiagnosticStatus.WARN if bad else DiagnosticStatus.OK
        s.message = f'{sum(self.counts.values())} observations, {bad} failed'
        s.values = [KeyValue(key=k, value=str(v)) for k, v in sorted(self.counts.items())]
        s.values += [
            KeyValue(key='pending', value=str(len(self.pending))),
            KeyValue(key='frames_buffered', value=str(len(self.frames))),
            KeyValue(key='camera_info', value=str(self.camera is not None)),
        ]
        arr = DiagnosticArray(status=[s])
        arr.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(arr)


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, ImagingError)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    try:
        node = ImagerNode()
    except STARTUP_ERRORS as exc:
        print(f'imager: error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
