"""The ``camera`` node: a camera opened with OpenCV (``VideoCapture``), as a ROS 2 driver.

Publishes ``<camera_id>/image_raw`` (``mono8`` or ``bgr8``) and ``<camera_id>/camera_info``
(from ``camera_info_file``, a calibration YAML as ``camera_calibration`` writes it) best effort,
as camera drivers do, each frame stamped on the wall clock when it was read (the imager
subtracts the hardware file's ``exposure_delay``). It free-runs: the device sets the rate, a
video file plays at ``frame_rate``. A device that stops giving frames is reopened every
``reconnect_period``; /diagnostics says how many frames came and how often it failed.

``trigger: software`` (the hardware file's ``trigger: software`` for a ``device:`` source): the
node offers ``~/trigger`` (``std_srvs/Trigger``) and publishes, for each call, the first frame
whose exposure (read time minus ``exposure_delay``) began at or after the call, and no other
frame. OpenCV's ``VideoCapture`` cannot start a sensor's exposure (a UVC or GigE camera behind it
streams at its own rate), so the node keeps reading the stream (its buffer stays fresh) and
chooses: the frame's exposure falls within one frame period after the call. The imager calls
half a period ahead of the instant (see ``hardware_graph.imager_config``), so the frame is the
one nearest the instant, published at once and alone: nothing else crosses DDS or is decoded.

Parameters: see ``config/camera.yaml``.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any

import cv2
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image
from std_srvs.srv import Trigger

from activesurv_common.camera_model import CameraModel
from activesurv_common.ros import diagnostics, qos, topics
from activesurv_common.ros.conversions import CameraInfoStamper, gray_to_image
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_hardware.errors import CameraSourceError, HardwareError
from activesurv_hardware.video_source import VideoSource, is_file

PARAMS = (
    Param('camera_id', 'cam1', 'topic prefix and frame (<camera_id>_optical_frame)'),
    Param('device', '0', 'VideoCapture device: index, /dev/videoN, file, pipeline or URL'),
    Param('width', 0, 'requested width (px); 0: the device default', minimum=0),
    Param('height', 0, 'requested height (px); 0: the device default', minimum=0),
    Param('fps', 0.0, 'requested device rate (Hz); 0: the device default', minimum=0.0),
    Param('fourcc', '', 'requested pixel format, e.g. MJPG or YUYV'),
    Param('frame_rate', 30.0, 'Hz a video file is played at', above=0.0),
    Param('loop', False, 'play a video file again from its start when it ends'),
    Param('encoding', 'mono8', 'published encoding', choices=('mono8', 'bgr8')),
    Param('camera_info_file', '', 'calibration YAML (camera_calibration format); empty: none'),
    Param('reconnect_period', 1.0, 's between attempts to reopen the device', above=0.0),
    Param(
        'trigger',
        'free',
        'free: publish every frame; software: only the first frame exposed after each call '
        'of ~/trigger (std_srvs/Trigger)',
        choices=('free', 'software'),
    ),
    Param(
        'exposure_delay',
        0.0,
        "s from a frame's exposure to its read (software trigger: which frame began after "
        'the call)',
        minimum=0.0,
        maximum=1.0,
    ),
    Param('trigger_queue', 16, 'software trigger: calls kept waiting for a frame', minimum=1),
)


class CameraNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('camera', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.camera_id = str(v['camera_id'])
        self.frame_id = f'{self.camera_id}_optical_frame'
        self.encoding = str(v['encoding'])
        options = {k: v[k] for k in ('width', 'height', 'fps') if v[k]}
        if v['fourcc']:
            options['fourcc'] = str(v['fourcc'])
        self.device = str(v['device'])
        self.source = VideoSource(self.device, options, bool(v['loop']))
        self.period = 1.0 / float(v['frame_rate']) if is_file(self.device) else 0.0
        self.reconnect = float(v['reconnect_period'])
        self.model: CameraModel | None = None
        if v['camera_info_file']:
            self.model = CameraModel.load(str(v['camera_info_file']))
        self.info = CameraInfoStamper(self.model, self.frame_id) if self.model else None
        self.last_error = ''
        self.triggered = v['trigger'] == 'software'
        self.exposure_delay = float(v['exposure_delay'])
        # Software trigger: the calls (wall-clock s) still waiting for their frame.
        self._armed: deque[float] = deque(maxlen=int(v['trigger_queue']))
        self._lock = threading.Lock()
        self.triggers = self.published = self.skipped = 0
        if self.triggered:
            self.create_service(Trigger, '~/trigger', self._on_trigger)
        self._image_pub = self.create_publisher(Image, topics.image(self.camera_id), qos.SENSOR)
        self._info_pub = self.create_publisher(
            CameraInfo, topics.camera_info(self.camera_id), qos.SENSOR
        )
        self._diag_pub = self.create_publisher(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_timer(1.0, self._publish_diagnostics)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        """Read frames as the device gives them (its own rate), publish each at once."""
        next_t = time.monotonic()
        while not self._stop.is_set():
            try:
                if not self.source.opened:
                    self.source.open()
                    self.get_logger().info(f'{self.camera_id}: opened {self.device!r}')
                frame = self.source.read()
            except CameraSourceError as exc:
                self.last_error = str(exc)
                self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
                self._stop.wait(self.reconnect)
                continue
            now = self.get_clock().now()
            if not self.triggered or self._take(now.nanoseconds * 1e-9):
                self._publish(frame, now.to_msg())
            if self.period:
                next_t += self.period
                self._stop.wait(max(0.0, next_t - time.monotonic()))

    def _on_trigger(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self._lock:
            self._armed.append(self.get_clock().now().nanoseconds * 1e-9)
            self.triggers += 1
        response.success = True
        response.message = 'armed: the next frame exposed from now is published'
        return response

    def _take(self, read_at: float) -> bool:
        """Whether the frame read at ``read_at`` answers a waiting call (it began exposing at
        or after the call); answers every call it is the first such frame for."""
        exposed = read_at - self.exposure_delay
        with self._lock:
            answered = 0
            while self._armed and self._armed[0] <= exposed:
                self._armed.popleft()
                answered += 1
            if not answered:
                self.skipped += 1
                return False
            self.published += 1
            return True

    def _publish(self, frame: Any, stamp: Any) -> None:
        if frame.ndim == 2 or self.encoding == 'mono8':
            gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
            msg = gray_to_image(gray, self.frame_id, stamp)
        else:
            msg = gray_to_image(frame.reshape(frame.shape[0], -1), self.frame_id, stamp)
            msg.width, msg.encoding, msg.step = frame.shape[1], 'bgr8', 3 * frame.shape[1]
        self._image_pub.publish(msg)
        if self.info is not None:
            self._info_pub.publish(self.info(stamp))

    def _publish_diagnostics(self) -> None:
        ok = self.source.opened
        s = diagnostics.status(
            f'activesurv/camera/{self.camera_id}',
            self.camera_id,
            f'{self.source.frames} frames' if ok else f'not open: {self.last_error}',
            dict(
                frames=self.source.frames,
                failures=self.source.failures,
                device=self.device,
                trigger='software' if self.triggered else 'free',
                triggers=self.triggers,
                published=self.published if self.triggered else self.source.frames,
            ),
            diagnostics.OK if ok else diagnostics.ERROR,
        )
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.source.close()


def main(args: list[str] | None = None) -> int:
    return run_node('camera', CameraNode, args, on_stop=CameraNode.close, errors=(HardwareError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
