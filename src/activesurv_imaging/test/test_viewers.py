"""An imager's views of an observation (annotations, the demand frame) leave after it, and
nothing waiting is lost when the node stops (``activesurv_imaging.ros.viewers``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.observation import failed


def _frame(sec: int) -> Any:
    from sensor_msgs.msg import Image

    msg = Image()
    msg.header.stamp.sec, msg.header.frame_id = sec, 'vw1_optical_frame'
    msg.height, msg.width, msg.step, msg.encoding = 4, 4, 4, 'mono8'
    msg.data = bytes(range(16))
    return msg


def test_views_wait_their_delay_and_a_stop_flushes_them(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from sensor_msgs.msg import CompressedImage
    from visualization_msgs.msg import ImageMarker

    from activesurv_common.ros import qos, topics
    from activesurv_imaging.ros.viewers import ObservationViews

    imager = rclpy_context.create_node('views_imager')
    viewer = rclpy_context.create_node('views_viewer')
    marks: list[Any] = []
    frames: list[Any] = []
    try:
        viewer.create_subscription(
            ImageMarker, topics.marker_annotations('vw1'), marks.append, qos.EVENTS
        )
        viewer.create_subscription(
            CompressedImage, topics.demand_frame('vw1'), frames.append, qos.EVENTS
        )
        soon = ObservationViews(imager, 'vw1', record_frames=True, delay=0.05)
        why = 'no marker-sized bright region'
        obs = failed('vw1', 3, 5.0, ObservationStatus.NOT_FOUND, why)
        assert spin_until(
            [imager, viewer], lambda: imager.count_subscribers(topics.demand_frame('vw1')) >= 1
        )
        start = time.monotonic()
        soon.publish(obs, None, _frame(5))
        assert len(soon.later) == 1  # waiting, not published
        assert spin_until([imager, viewer], lambda: bool(marks) and bool(frames))
        assert time.monotonic() - start >= 0.05
        assert marks[0].ns.startswith('demand 3: not_found')  # the failure, with its reason
        assert frames[0].header.stamp.sec == 5  # the frame measured, stamped as it was
        marks.clear()
        frames.clear()
        later = ObservationViews(imager, 'vw1', record_frames=True, delay=60.0)
        later.publish(obs, None, _frame(6))
        later.flush()  # the node stops: what waits goes out now
        assert len(later.later) == 0
        assert spin_until([imager, viewer], lambda: bool(marks) and bool(frames), 5.0)
        assert frames[0].header.stamp.sec == 6
    finally:
        for node in (imager, viewer):
            node.destroy_node()
