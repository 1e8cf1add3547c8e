"""What an imager publishes for people after each observation, off the instant's critical path.

The viewers' annotations (``<camera>/marker_annotations``: the ellipse, its centre, the chosen
normal, or the failure), the demand's frame for the bag (``<camera>/demand_frame``, PNG, with
``record_frames``) and a failure's warning. None of it is on the way to an estimate, and at a
demand instant the other cameras are still imaging on the same cores: it goes out
``viewers_delay`` seconds after the observation (:class:`activesurv_common.ros.deferred.
Deferred`; 0: at once), and all that waits goes out when the node stops (:meth:`flush`).
"""

from __future__ import annotations

import math
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import CompressedImage
from visualization_msgs.msg import ImageMarker

from activesurv_common.camera_model import CameraModel
from activesurv_common.ros import qos, topics
from activesurv_common.ros.deferred import Deferred
from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.annotations import annotation_shapes
from activesurv_imaging.conversions import annotation_markers, demand_frame_msg
from activesurv_imaging.observation import Observation


class ObservationViews:
    """An imager's annotations, demand frames and failure warnings, ``delay`` s late."""

    def __init__(self, node: Node, camera_id: str, record_frames: bool, delay: float) -> None:
        self._log = node.get_logger()  # type: ignore[no-untyped-call]
        self.frame_id = f'{camera_id}_optical_frame'
        self._ann_pub = node.create_publisher(
            ImageMarker, topics.marker_annotations(camera_id), qos.EVENTS
        )
        self._frame_pub = (
            node.create_publisher(CompressedImage, topics.demand_frame(camera_id), qos.EVENTS)
            if record_frames
            else None
        )
        self.later = Deferred(node, delay)

    @property
    def records_frames(self) -> bool:
        return self._frame_pub is not None

    def publish(self, obs: Observation, camera: CameraModel | None, image: Any = None) -> None:
        """After ``obs`` was published: its views, on ``camera``'s image; ``image`` (the
        frame it was measured on, a sensor_msgs/Image) is recorded with ``record_frames``."""
        self.later(lambda: self._publish(obs, camera, image))

    def flush(self) -> int:
        """Publish every view still waiting, now (the node stops); returns how many."""
        return self.later.flush()

    def _publish(self, obs: Observation, camera: CameraModel | None, image: Any) -> None:
        size = (camera.width, camera.height) if camera is not None else (640, 480)
        project = camera.project if camera is not None else None
        shapes = annotation_shapes(obs, project, image_size=size)
        for m in annotation_markers(shapes, obs.stamp, self.frame_id, obs.demand_index):
            self._ann_pub.publish(m)
        if obs.status is not ObservationStatus.OK:
            self._log.warning(f'demand {obs.demand_index}: {obs.status.name}: {obs.reason}')
        if self._frame_pub is not None and image is not None and math.isfinite(obs.stamp):
            self._frame_pub.publish(demand_frame_msg(image, self.frame_id))
