"""The ``image_load`` node: camera-like image streams as background load, and their receiver.

``role: stream`` publishes, for each of ``camera_ids``, ``width`` x ``height`` rgb8 images at
``rate`` Hz on ``<cam>/stream/image_raw`` (best effort, like camera drivers), each stamped with
the wall time and numbered in ``header.frame_id`` (``cam1:17``). ``role: count`` subscribes to
the same streams and, when stopped, writes to ``summary_file`` how many frames of each stream
arrived and how many were lost (gaps in the numbering) and the median transport delay. The
load benchmark runs both next to an experiment graph (``bench/bench_reliability.py``).

With ``raw: true`` (default) the counter takes the serialized messages and reads only the
header from the CDR bytes, so that it measures what DDS delivers rather than how fast Python
turns 900 kB into a message object; ``raw: false`` deserializes every frame, like a Python
image consumer would.
"""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_recording.bagio import cdr_header


def stream_topic(camera_id: str) -> str:
    return f'{camera_id}/stream/image_raw'


PARAMS = (
    Param('role', 'stream', 'stream images or count them', choices=('stream', 'count')),
    Param('camera_ids', ['cam1', 'cam2', 'cam3', 'cam4'], 'one stream per camera'),
    Param('rate', 30.0, 'Hz per stream', above=0.0),
    Param('width', 640, 'image width (px)', minimum=1),
    Param('height', 480, 'image height (px)', minimum=1),
    Param('summary_file', '', 'count role: JSON written here on stop'),
    Param('raw', True, 'count role: read only stamp and sequence from the CDR bytes'),
)


class ImageLoadNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('image_load', **kwargs)
        declare(self, PARAMS)
        g = self.get_parameter
        self.role = str(g('role').value)
        self.cameras = [str(c) for c in g('camera_ids').value]
        rate = float(g('rate').value)
        w, h = int(g('width').value), int(g('height').value)
        if self.role not in ('stream', 'count'):
            raise ValueError(f'role must be stream or count, got {self.role!r}')
        if not (0.0 < rate <= 1000.0) or not (0 < w <= 8192) or not (0 < h <= 8192):
            raise ValueError('rate must be in (0, 1000] Hz and the image size in 1..8192')
        self.seq = dict.fromkeys(self.cameras, 0)
        self.got: dict[str, list[int]] = {c: [] for c in self.cameras}
        self.delay: list[float] = []
        if self.role == 'stream':
            pixels = np.random.default_rng(0).integers(0, 255, size=(h, w, 3), dtype=np.uint8)
            self.msgs = {}  # one message per stream, built once: only the header changes
            for c in self.cameras:
                msg = Image(height=h, width=w, encoding='rgb8', step=3 * w)
                msg.data = pixels.tobytes()
                self.msgs[c] = msg
            self.pubs = {
                c: self.create_publisher(Image, stream_topic(c), qos_profile_sensor_data)
                for c in self.cameras
            }
            self.create_timer(
                1.0 / rate, self._publish, clock=Clock(clock_type=ClockType.STEADY_TIME)
            )
        else:
            raw = bool(g('raw').value)
            for c in self.cameras:
                self.create_subscription(
                    Image,
                    stream_topic(c),
                    self._receive_raw(c) if raw else self._receive(c),
                    qos_profile_sensor_data,
                    raw=raw,
                )

    def _publish(self) -> None:
        for c, pub in self.pubs.items():
            msg = self.msgs[c]
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = f'{c}:{self.seq[c]}'
            pub.publish(msg)
            self.seq[c] += 1

    def _count(self, camera_id: str, sent: float, frame_id: str) -> None:
        try:
            self.got[camera_id].append(int(frame_id.rsplit(':', 1)[1]))
        except (IndexError, ValueError):
            return
        self.delay.append(time.time() - sent)

    def _receive(self, camera_id: str) -> Any:
        def callback(msg: Image) -> None:
            sent = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            self._count(camera_id, sent, msg.header.frame_id)

        return callback

    def _receive_raw(self, camera_id: str) -> Any:
        def callback(data: bytes) -> None:
            try:
                sent, frame_id = cdr_header(data)
            except ValueError:
                return
            self._count(camera_id, sent, frame_id)

        return callback

    def summary(self) -> dict[str, Any]:
        streams = {}
        for c, seqs in self.got.items():
            expected = (max(seqs) - min(seqs) + 1) if seqs else 0
            streams[c] = {'received': len(seqs), 'expected': expected}
        received = sum(s['received'] for s in streams.values())
        expected = sum(s['expected'] for s in streams.values())
        return {
            'streams': streams,
            'received': received,
            'expected': expected,
            'dropped_fraction': 1.0 - received / expected if expected else None,
            'median_delay_ms': 1e3 * statistics.median(self.delay) if self.delay else None,
        }


def write_summary(node: ImageLoadNode) -> None:
    out = str(node.get_parameter('summary_file').value)
    if node.role == 'count' and out:
        Path(out).write_text(json.dumps(node.summary(), indent=2))


def main(args: list[str] | None = None) -> int:
    return run_node('image_load', ImageLoadNode, args, on_stop=write_summary)


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
