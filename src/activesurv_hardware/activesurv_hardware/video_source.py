"""A camera opened with OpenCV's ``VideoCapture``: what the ``camera`` node publishes.

``device`` is what ``VideoCapture`` takes: a number (``0``: the first V4L2 camera), a device
path (``/dev/video2``), a video file, a GStreamer pipeline (recognised by its ``!``; OpenCV must
be built with GStreamer) or a network stream (``rtsp://``, ``http://``, through FFmpeg).
``options`` set the capture's width, height, fps and fourcc (``MJPG``, ``YUYV``) where the
device takes them. A video file is played at ``frame_rate`` and loops when told to.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from activesurv_hardware.errors import CameraSourceError

Frame = NDArray[np.uint8]
PROPERTIES = {
    'width': cv2.CAP_PROP_FRAME_WIDTH,
    'height': cv2.CAP_PROP_FRAME_HEIGHT,
    'fps': cv2.CAP_PROP_FPS,
}
STREAMS = ('rtsp://', 'rtsps://', 'http://', 'https://', 'udp://', 'tcp://')


def parse_device(device: str) -> tuple[int | str, int]:
    """What to hand ``VideoCapture``: (index or path/URL/pipeline, backend API)."""
    d = device.strip()
    if not d:
        raise CameraSourceError('empty camera device')
    if d.isdigit():
        return int(d), cv2.CAP_ANY
    if '!' in d:
        return d, cv2.CAP_GSTREAMER
    if d.startswith(STREAMS):
        return d, cv2.CAP_FFMPEG
    return d, cv2.CAP_ANY


def is_file(device: str) -> bool:
    """A recorded video (played at a set rate) rather than a live camera."""
    d = device.strip()
    return not (d.isdigit() or '!' in d or d.startswith(STREAMS) or d.startswith('/dev/'))


class VideoSource:
    """Frames from one ``VideoCapture`` device, reopened after a failure."""

    def __init__(
        self,
        device: str,
        options: Mapping[str, Any] | None = None,
        loop: bool = False,
        opener: Callable[[int | str, int], Any] | None = None,
    ) -> None:
        self.device = device
        self.options = dict(options or {})
        self.loop = loop
        self._opener = opener
        self._cap: Any = None
        self.frames = 0
        self.failures = 0

    @property
    def opened(self) -> bool:
        return self._cap is not None

    def open(self) -> None:
        """Open the device and apply the options.

        Raises:
            CameraSourceError: if it cannot be opened (with what was tried).
        """
        self.close()
        target, api = parse_device(self.device)
        cap = (self._opener or _video_capture)(target, api)
        if cap is None or not cap.isOpened():
            self.failures += 1
            raise CameraSourceError(f'cannot open camera {self.device!r} with OpenCV')
        fourcc = self.options.get('fourcc')
        if fourcc:
            cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*str(fourcc)[:4]))
        for key, prop in PROPERTIES.items():
            if key in self.options:
                cap.set(prop, float(self.options[key]))
        self._cap = cap

    def read(self) -> Frame:
        """The next frame (grey or BGR).

        Raises:
            CameraSourceError: when the device gives no frame (closed, unplugged, file ended
                without ``loop``); the source is closed and may be opened again.
        """
        if self._cap is None:
            raise CameraSourceError(f'camera {self.device!r} is not open')
        ok, frame = self._cap.read()
        if not ok and self.loop:
            self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, frame = self._cap.read()
        if not ok or frame is None:
            self.failures += 1
            self.close()
            raise CameraSourceError(f'camera {self.device!r} gave no frame')
        self.frames += 1
        return np.asarray(frame, dtype=np.uint8)

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def _video_capture(target: int | str, api: int) -> Any:
    return cv2.VideoCapture(target, api)
