"""A simulated camera's frame as the two messages it goes out in, built ahead when it can be.

A frame rendered ahead of its demand instant (:mod:`activesurv_sim.ros.ahead`) is sent at the
instant, on the camera's own trigger; building its ``CameraInfo`` and ``Image`` then took
0.2 ms of CPU per camera between the trigger and the imager's first look at the frame
(docs/performance.md). :class:`FrameMessages` builds them when the frame is rendered and hands
them over at the instant; any other frame (a stream, a frame rendered late, a frozen camera's
repeated pixels) gets its messages built when sent.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from sensor_msgs.msg import CameraInfo, Image

from activesurv_common.camera_model import CameraModel
from activesurv_common.ros.conversions import CameraInfoStamper, gray_to_image, sec_to_time

KEPT = 8
"""Instants whose messages are held ready at once (a camera has one or two pending)."""


class FrameMessages:
    """``(CameraInfo, Image)`` of a frame stamped ``t``: made ahead by :meth:`prepare`, or
    now."""

    def __init__(self, model: CameraModel, frame_id: str) -> None:
        self.frame_id = frame_id
        self.info = CameraInfoStamper(model, frame_id)
        self._ready: dict[float, tuple[NDArray[np.uint8], CameraInfo, Image]] = {}
        self.prepared = 0  # frames whose messages were built ahead and used

    def prepare(self, t: float, frame: NDArray[np.uint8]) -> None:
        """Build the messages of ``frame``, to be sent stamped ``t``."""
        held = self._ready.get(t)
        if held is not None and held[0] is frame:
            return
        stamp = sec_to_time(t)
        self._ready[t] = (frame, self.info(stamp), gray_to_image(frame, self.frame_id, stamp))
        for old in sorted(self._ready)[:-KEPT]:  # instants that passed without their frame
            del self._ready[old]

    def __call__(self, t: float, frame: NDArray[np.uint8]) -> tuple[CameraInfo, Image]:
        """The messages of ``frame`` stamped ``t``: those built ahead for this very frame, or
        new ones."""
        held = self._ready.pop(t, None)
        if held is not None and held[0] is frame:
            self.prepared += 1
            return held[1], held[2]
        stamp = sec_to_time(t)
        return self.info(stamp), gray_to_image(frame, self.frame_id, stamp)
