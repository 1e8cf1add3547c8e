"""The ``overhead_locator`` node: the top marker's world position in every overhead image.

Subscribes: <camera_id>/image_raw, <camera_id>/camera_info (the static overhead camera).
Publishes: overhead/fix (geometry_msgs/PointStamped in ``world``, stamped with the image's
    exposure time; one per image in which the marker was found), /diagnostics,
    activesurv/ready (with ``wait_for_readers``: its name once its fixes have those readers).
Parameters: see ``config/overhead_locator.yaml``. The camera's pose comes from
``extrinsics_file`` (``activesurv_calibrate extrinsics``) or ``camera_pose``.

This is the vision half of the paper's Prediction Module; the ``predictor`` node tracks the
fixes with the Kalman filter.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from geometry_msgs.msg import PointStamped, Pose, PoseArray
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.ros import diagnostics, local_topics, qos, ready, topics
from activesurv_common.ros.conversions import image_to_gray, model_from_camera_info
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_imaging.conversions import info_disagreement
from activesurv_imaging.errors import VisionErrors
from activesurv_imaging.kernels import warm_up
from activesurv_imaging.overhead import load_extrinsics, overhead_fix, overhead_fixes


def _seven_numbers(v: Any) -> str | None:
    return None if len(v) == 7 else 'camera_pose needs 7 numbers: x, y, z, qx, qy, qz, qw'


PARAMS = (
    Param('camera_id', topics.OVERHEAD, 'overhead camera id (topic prefix)'),
    Param('extrinsics_file', '', 'YAML from activesurv_calibrate extrinsics; empty: camera_pose'),
    Param(
        'camera_pose',
        [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0],
        'overhead x, y, z, qx, qy, qz, qw in world, if no extrinsics_file',
        check=_seven_numbers,
    ),
    Param('marker_height', 0.08, 'z of the top marker plane (m)'),
    Param('marker_radius', 0.0125, 'top marker radius (m)', above=0.0),
    Param('frame_id', 'world', 'frame of the fixes'),
    Param('all_markers', False, 'several objects: every marker of a frame on overhead/fixes'),
    Param(
        'wait_for_readers',
        0,
        'readers its fixes must have matched before it says so on activesurv/ready (0: none)',
        minimum=0,
        maximum=64,
    ),
    Param(
        'camera_info_file',
        '',
        'commissioned intrinsics (camera_calibration YAML), used over the camera_info topic',
    ),
)


class OverheadLocatorNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('overhead_locator', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.camera_id = str(v['camera_id'])
        pose = [float(x) for x in v['camera_pose']]
        self.T_world_camera = (
            load_extrinsics(str(v['extrinsics_file']))
            if v['extrinsics_file']
            else Transform.from_rt(matrix_from_quaternion(pose[3:]), pose[:3])
        )
        self.marker_height = float(v['marker_height'])
        self.marker_radius = float(v['marker_radius'])
        self.frame_id = str(v['frame_id'])
        warm_up()  # the imaging kernels compiled (make setup) or loaded before the first frame
        self.camera: CameraModel | None = None
        self._from_file = bool(v['camera_info_file'])
        if self._from_file:  # a driver's camera_info is then only compared with it
            self.camera = CameraModel.load(str(v['camera_info_file']))
        self.counts: Counter[str] = Counter()
        self.last_reason = ''
        self._fix_pub = self.create_publisher(PointStamped, topics.OVERHEAD_FIX, qos.STATE)
        self.all_markers = bool(v['all_markers'])
        self._fixes_pub = (
            self.create_publisher(PoseArray, topics.OVERHEAD_FIXES, qos.STATE)
            if self.all_markers
            else None
        )
        self._diag_pub = self.create_publisher(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        # From the overhead camera in its container: in process only (no copy through DDS),
        # its intrinsics before each frame; from a driver elsewhere over DDS.
        image, info = topics.image(self.camera_id), topics.camera_info(self.camera_id)
        for msg_type, topic, callback in (
            (Image, image, self._on_image),
            (CameraInfo, info, self._on_info),
        ):
            local_topics.subscription(self, msg_type, topic, callback, qos.SENSOR, only_local=True)
        if (readers := int(v['wait_for_readers'])) > 0:  # a simulated run's time waits for it
            fixes = topics.OVERHEAD_FIXES if self.all_markers else topics.OVERHEAD_FIX
            ready.announce_when_matched(self, outputs={fixes: readers})
        self.create_timer(1.0, self._publish_diagnostics)

    def _on_info(self, msg: CameraInfo) -> None:
        if self.camera is not None:
            if self._from_file and not self.counts['camera_info_compared']:
                self.counts['camera_info_compared'] += 1
                why = info_disagreement(self.camera, msg, self.camera_id, 2.0)
                if why:
                    self.get_logger().warning(why)
            return
        try:
            self.camera = model_from_camera_info(msg, self.camera_id)
        except VisionErrors as exc:
            self.counts['bad_camera_info'] += 1
            self.get_logger().error(f'bad camera_info: {exc}', throttle_duration_sec=5)

    def _on_image(self, msg: Image) -> None:
        self.counts['frames'] += 1
        if self.camera is None:
            self.last_reason = 'waiting for camera_info'
            return
        args = (self.camera, self.T_world_camera, self.marker_height, self.marker_radius)
        try:
            gray = image_to_gray(msg)
            # Several objects: every top marker of the frame; else the one marker.
            found = overhead_fixes(gray, *args) if self._fixes_pub else [overhead_fix(gray, *args)]
        except VisionErrors as exc:
            self.counts['bad_images'] += 1
            self.last_reason = f'bad image: {exc}'
            return
        xys = []
        for fix in found:
            if fix.xy is None:
                self.counts['no_fix'] += 1
                self.last_reason = fix.reason
            else:
                self.counts['fixes'] += 1
                xys.append(fix.xy)
        if self._fixes_pub is not None:  # one PoseArray (empty: the frame held no marker)
            out = PoseArray()
            out.header.stamp, out.header.frame_id = msg.header.stamp, self.frame_id
            for xy in xys:
                pose = Pose()
                pose.position.x, pose.position.y = (float(c) for c in xy)
                pose.position.z, pose.orientation.w = self.marker_height, 1.0
                out.poses.append(pose)
            self._fixes_pub.publish(out)
        elif xys:
            pt = PointStamped()
            pt.header.stamp, pt.header.frame_id = msg.header.stamp, self.frame_id
            pt.point.x, pt.point.y = (float(c) for c in xys[0])
            pt.point.z = self.marker_height
            self._fix_pub.publish(pt)

    def _publish_diagnostics(self) -> None:
        values: dict[str, Any] = dict(self.counts)
        values['last_no_fix_reason'] = self.last_reason
        s = diagnostics.status(
            'activesurv/overhead_locator',
            self.camera_id,
            f'{self.counts["fixes"]} fixes from {self.counts["frames"]} frames',
            values,
            diagnostics.OK if self.counts['fixes'] else diagnostics.WARN,
        )
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))


def main(args: list[str] | None = None) -> int:
    return run_node('overhead_locator', OverheadLocatorNode, args)


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
