"""The ``predictor`` node: overhead images in, the rolling horizon of demand points out.

Subscribes: <camera_id>/image_raw, <camera_id>/camera_info (the overhead camera).
Publishes: demand_horizon (activesurv_interfaces/DemandHorizon, latched), overhead/track
    (geometry_msgs/PointStamped, each accepted fix), /diagnostics.
Parameters: see ``config/predictor.yaml``.
"""

from __future__ import annotations

import math
import sys
from collections import deque
from pathlib import Path
from typing import Any, cast

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image

from activesurv_imaging.camera_model import CameraModel
from activesurv_imaging.conversions import (
    image_to_gray,
    model_from_camera_info,
    sec_to_time,
    time_to_sec,
)
from activesurv_imaging.errors import ImagingError
from activesurv_imaging.geometry import Transform, matrix_from_quaternion
from activesurv_interfaces.msg import DemandHorizon
from activesurv_prediction import qos, topics
from activesurv_prediction.conversions import horizon_to_msg
from activesurv_prediction.demands import DemandSchedule, TargetGeometry, predict_demands
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.overhead import overhead_fix
from activesurv_prediction.predictor import TargetPredictor
from activesurv_prediction.tracker import Tracker, TrackState, Workspace

POSITIVE = ('marker_radius', 'service_interval', 'measurement_std', 'jerk_std', 'lost_timeout')


def _load_extrinsics(path: str) -> Transform:
    try:
        data = yaml.safe_load(Path(path).read_text())
        T = data['T_world_camera']
        return Transform.from_rt(matrix_from_quaternion(T['rotation_xyzw']), T['translation'])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise PredictionError(f'cannot read overhead extrinsics {path}: {exc}') from exc


class PredictorNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('predictor', **kwargs)
        d = ParameterDescriptor
        self.declare_parameter('camera_id', 'overhead', d(description='overhead camera id'))
        self.declare_parameter(
            'extrinsics_file', '', d(description='YAML from activesurv_calibrate extrinsics')
        )
        self.declare_parameter(
            'camera_pose',
            [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0],
            d(description='overhead x,y,z,qx,qy,qz,qw if no extrinsics_file'),
        )
        self.declare_parameter('marker_height', 0.08, d(description='top marker plane z (m)'))
        self.declare_parameter('marker_radius', 0.0125, d(description='top marker radius (m)'))
        self.declare_parameter('first_demand', 4.0, d(description='first demand instant (s)'))
        self.declare_parameter('service_interval', 2.0, d(description='between demands (s)'))
        self.declare_parameter('demand_count', 10, d(description='number of demand instants'))
        self.declare_parameter(
            'demand_times',
            Parameter.Type.DOUBLE_ARRAY,
            d(description='explicit instants (s); unset: use the above'),
        )
        self.declare_parameter('horizon', 5, d(description='demands on the rolling horizon (m)'))
        self.declare_parameter('measurement_std', 0.5e-3, d(description='overhead fix std (m)'))
        self.declare_parameter('jerk_std', 2e-4, d(description='process noise (m/s^3)'))
        self.declare_parameter('gate', 50.0, d(description='chi-square outlier gate (2 dof)'))
        self.declare_parameter('confirm_fixes', 10, d(description='fixes to confirm a track'))
        self.declare_parameter('lost_timeout', 1.0, d(description='unseen s before track loss'))
        self.declare_parameter(
            'workspace', [0.0, 0.5, 0.0, 0.2], d(description='x_min, x_max, y_min, y_max (m)')
        )
        self.declare_parameter(
            'side_marker_offset',
            [0.0, -0.03, -0.03],
            d(description='side marker centre minus top marker centre (m)'),
        )
        self.declare_parameter(
            'side_marker_normal', [0.0, -1.0, 0.0], d(description='side marker normal (world)')
        )
        self.declare_parameter('frame_id', 'world', d(description='frame of the horizon'))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')

        g = self.get_parameter
        self.camera_id = str(g('camera_id').value)
        path = str(g('extrinsics_file').value)
        pose = [float(v) for v in g('camera_pose').value]
        self.T_world_camera = (
            _load_extrinsics(path)
            if path
            else Transform.from_rt(matrix_from_quaternion(pose[3:]), pose[:3])
        )
        times = g('demand_times').value
        self.schedule = (
            DemandSchedule.explicit(times)
            if times
            else DemandSchedule.regular(
                float(g('first_demand').value),
                float(g('service_interval').value),
                int(g('demand_count').value),
            )
        )
        self.geometry = TargetGeometry.create(
            g('side_marker_offset').value, g('side_marker_normal').value
        )
        self.tracker = Tracker(
            TargetPredictor(
                measurement_std=float(g('measurement_std').value),
                jerk_std=float(g('jerk_std').value),
                gate=float(g('gate').value),
            ),
            Workspace(*[float(v) for v in g('workspace').value]),
            confirm_fixes=int(g('confirm_fixes').value),
            lost_timeout=float(g('lost_timeout').value),
        )
        self.camera: CameraModel | None = None
        self._fix_times: deque[float] = deque(maxlen=60)
        self._innovations: deque[float] = deque(maxlen=300)
        self._no_fix_reason = ''
        self._frames = 0
        self._last_state = TrackState.NONE

        self._horizon_pub = self.create_publisher(
            DemandHorizon, topics.DEMAND_HORIZON, qos.LATCHED
        )
        self._track_pub = self.create_publisher(PointStamped, topics.OVERHEAD_TRACK, qos.SENSOR)
        self._diag_pub = self.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_subscription(Image, topics.image(self.camera_id), self._on_image, qos.SENSOR)
        self.create_subscription(
            CameraInfo, topics.camera_info(self.camera_id), self._on_info, qos.SENSOR
        )
        self.create_timer(0.1, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name in POSITIVE and (
                not isinstance(p.value, float) or not math.isfinite(p.value) or p.value <= 0.0
            ):
                return SetParametersResult(
                    successful=False, reason=f'{p.name} must be a finite float > 0'
                )
            if p.name in ('horizon', 'demand_count', 'confirm_fixes') and p.value < 1:
                return SetParametersResult(successful=False, reason=f'{p.name} must be >= 1')
            if p.name == 'workspace':
                try:
                    Workspace(*[float(v) for v in p.value])
                except (PredictionError, TypeError) as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_info(self, msg: CameraInfo) -> None:
        if self.camera is None:
            try:
                self.camera = model_from_camera_info(msg, self.camera_id)
            except ImagingError as exc:
                self.get_logger().error(f'bad camera_info: {exc}', throttle_duration_sec=5)

    def _on_image(self, msg: Image) -> None:
        self._frames += 1
        if self.camera is None:
            self._no_fix_reason = 'waiting for camera_info'
            return
        t = time_to_sec(msg.header.stamp)
        try:
            fix = overhead_fix(
                image_to_gray(msg),
                self.camera,
                self.T_world_camera,
                float(self.get_parameter('marker_height').value),
                float(self.get_parameter('marker_radius').value),
            )
        except ImagingError as exc:
            self._no_fix_reason = f'bad image: {exc}'
            self.get_logger().warning(self._no_fix_reason, throttle_duration_sec=5)
            return
        if fix.xy is None:
            self._no_fix_reason = fix.reason
            return
        result = self.tracker.update(t, fix.xy)
        if result is None:
            return
        if result.accepted:
            self._fix_times.append(t)
            pt = PointStamped()
            pt.header = msg.header
            pt.header.frame_id = str(self.get_parameter('frame_id').value)
            pt.point.x, pt.point.y = (float(v) for v in fix.xy)
            pt.point.z = float(self.get_parameter('marker_height').value)
            self._track_pub.publish(pt)
        else:
            self.get_logger().warning(
                f'outlier fix rejected (d2={result.mahalanobis2:.1f})', throttle_duration_sec=2
            )
        if math.isfinite(result.mahalanobis2):
            self._innovations.append(result.mahalanobis2)
        self._publish_horizon(t)

    def _publish_horizon(self, now: float) -> None:
        state = self.tracker.state
        preds = []
        if state in (TrackState.TENTATIVE, TrackState.CONFIRMED):
            preds = predict_demands(
                self.tracker.predictor,
                self.schedule,
                self.geometry,
                float(self.get_parameter('marker_height').value),
                now,
                int(self.get_parameter('horizon').value),
            )
        self._horizon_pub.publish(
            horizon_to_msg(preds, state, now, str(self.get_parameter('frame_id').value))
        )
        if state is not self._last_state:
            self.get_logger().info(f'track {self._last_state.name} -> {state.name}')
            self._last_state = state

    def _on_tick(self) -> None:
        if self.tracker.check_timeout(self._now()):
            self.get_logger().warning('track lost: object not seen for too long')
            self._publish_horizon(self._now())

    def _publish_diagnostics(self) -> None:
        s = DiagnosticStatus(name='activesurv/predictor', hardware_id=self.camera_id)
        state = self.tracker.state
        s.level = DiagnosticStatus.OK if state is TrackState.CONFIRMED else DiagnosticStatus.WARN
        s.message = f'track {state.name}'
        ts = list(self._fix_times)
        rate = (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 1 and ts[-1] > ts[0] else 0.0
        inn = np.array(self._innovations) if self._innovations else np.array([math.nan])
        p = self.tracker.predictor
        s.values = [
            KeyValue(key='track_state', value=state.name),
            KeyValue(key='update_rate_hz', value=f'{rate:.1f}'),
            KeyValue(key='frames', value=str(self._frames)),
            KeyValue(key='innovation_d2_mean', value=f'{float(np.mean(inn)):.2f}'),
            KeyValue(key='innovation_d2_p95', value=f'{float(np.percentile(inn, 95)):.2f}'),
            KeyValue(key='outliers_rejected', value=str(p.rejections)),
            KeyValue(key='tracks_started', value=str(self.tracker.tracks_started)),
            KeyValue(key='last_no_fix_reason', value=self._no_fix_reason),
        ]
        arr = DiagnosticArray(status=[s])
        arr.header.stamp = sec_to_time(self._now())
        self._diag_pub.publish(arr)


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, PredictionError)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    try:
        node = PredictorNode()
    except STARTUP_ERRORS as exc:
        print(f'predictor: error: {exc}', file=sys.stderr)
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
