"""The ``recorder`` node: records every topic of the graph to an MCAP rosbag2 bag.

Like ``ros2 bag record -a`` (not on PyPI): a topic is recorded once a publisher of it appears,
subscribed to match its publishers (reliable / transient local only if they all are) and noted in
``metadata.yaml`` with the QoS profiles they offer (what ``replay`` and ``ros2 bag play`` offer
again); its own status topic never. Messages are written as received (serialized bytes), stamped on
simulated time with the last /clock tick extrapolated at the ticks' rate
(:class:`~activesurv_common.timeseries.ClockEstimate`: latencies are read off these times). Streams
in ``thin_topics`` (the overhead camera) are thinned to ``image_rate`` Hz; every other message is
kept. Message definitions go into the bag; ``run_info`` (JSON) is stored on
``/activesurv/run_info``. On SIGINT/SIGTERM the bag is closed cleanly. Parameters: see
``config/recorder.yaml`` (``max_bag_duration`` splits the bag into bag_0.mcap, bag_1.mcap, ... of
one metadata.yaml; ``strip_namespace`` records a rig's /NS/x as /x). A SIGKILL loses at most the
messages of the last ``flush_period`` (default 0.5 s wall time): every flush writes a complete MCAP
chunk and fsyncs it; ``activesurv bag reindex BAG`` rebuilds the index and ``metadata.yaml`` from
what is on disk."""

from __future__ import annotations

import contextlib
import errno
import json
import threading
import time
from pathlib import Path
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String

from activesurv_common.pacing import Backoff
from activesurv_common.ros import qos, topics
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import declare
from activesurv_common.timeseries import ClockEstimate
from activesurv_recording.bagio import (
    RUN_INFO_TOPIC,
    BagWriter,
    SplitBagWriter,
    open_writer,
    strip_namespace,
)
from activesurv_recording.conversions import feed_clock, message_class, recording_qos
from activesurv_recording.errors import BagError
from activesurv_recording.recorder_params import PARAMS

STATUS_TOPIC = topics.RECORDER_STATUS


class RecorderNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('recorder', **kwargs)
        declare(self, PARAMS)
        g = self.get_parameter
        if not (output := str(g('output').value)):
            raise BagError('recorder needs the output parameter (a new bag directory)')
        split, self.latched = float(g('max_bag_duration').value), set[str]()
        size_mb, keep = float(g('max_bag_size').value), int(g('keep_bags').value)
        self.bag: BagWriter | SplitBagWriter | None = (
            SplitBagWriter(Path(output), split, self.latched, keep, int(size_mb * 1e6))
            if split or size_mb
            else open_writer(Path(output))
        )
        self.image_period = 1.0 / float(g('image_rate').value) if g('image_rate').value else 0.0
        self.exclude = set(g('exclude').value)
        self.namespace = str(g('strip_namespace').value)
        self.subscribed, self.last_image = dict[str, str](), dict[str, float]()
        self.counts: dict[str, int] = {}
        self.thin = set(g('thin_topics').value)
        self.sim_time = bool(g('use_sim_time').value)
        self.clock, self.clock_heard = ClockEstimate(), False
        self._lock = threading.Lock()
        try:
            info = json.loads(str(g('run_info').value))
        except ValueError as exc:
            raise BagError(f'run_info is not JSON: {exc}') from exc
        # Bags of this recorder note the QoS their publishers offered (replay trusts them).
        # (A run record's ``recorder`` field; any other JSON object gets the key too.)
        if not isinstance(info, dict):
            raise BagError('run_info must be a JSON object')
        info['recorder'] = {**(info.get('recorder') or {}), 'qos': 'offered'}
        self.bag.write_json(RUN_INFO_TOPIC, 0, info)
        # On the wall clock (simulated time: nothing ticks before /clock), backing off while idle.
        base, most = float(g('discovery_period').value), float(g('discovery_period_max').value)
        self._backoff = Backoff(base, max(most, base))
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._discovery = self.create_timer(base, self._discover, clock=steady)
        self.exclude.add(STATUS_TOPIC)  # never our own status
        self._discover()
        if not (flush_period := float(g('flush_period').value)) > 0.0:
            raise BagError(f'flush_period must be > 0 s, got {flush_period}')
        self.create_timer(flush_period, self._flush, clock=steady)
        self._status_pub = self.create_publisher(String, STATUS_TOPIC, qos.STATUS)

    def _flush(self) -> None:
        with self._lock:
            try:
                if self.bag is not None:
                    self.bag.flush()
            except OSError as exc:  # a full disk: close what can be closed, stop the run
                self._give_up(exc)
            counts = dict(self.counts)
        # Orchestrators wait on this before stopping the graph (nothing left unrecorded).
        self._status_pub.publish(String(data=json.dumps(counts)))

    def _qos(self, topic: str) -> tuple[QoSProfile, Any] | None:
        publishers = self.get_publishers_info_by_topic(topic)
        return recording_qos(publishers, qos.published_depth(topic)) if publishers else None

    def _discover(self) -> None:
        n = len(self.subscribed)
        self._look()
        # No backing off while simulated time waits (for every topic to be recorded: graph.py).
        found = len(self.subscribed) > n or (self.sim_time and not self.clock_heard)
        self._discovery.timer_period_ns = int(1e9 * self._backoff.after(found))

    def _look(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subscribed or topic in self.exclude or not types:
                continue
            qos_pair = self._qos(topic)
            if qos_pair is None:
                continue  # only subscribers so far: wait for a publisher to know its QoS
            type_name = types[0]
            try:
                cls = message_class(type_name)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f'cannot record {topic}: unknown type {type_name}')
                self.subscribed[topic] = type_name
                continue
            profile, offered = qos_pair
            if profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
                self.latched.add(topic)  # a split bag repeats its last message in every file
            with self._lock:
                assert self.bag is not None
                self.bag.connection(strip_namespace(topic, self.namespace), type_name, offered)
            self.create_subscription(
                cls, topic, self._callback(topic, type_name), profile, raw=True
            )
            self.subscribed[topic] = type_name
            self.get_logger().info(f'recording {topic} [{type_name}]')

    def _callback(self, topic: str, type_name: str) -> Any:
        thinned = topic in self.thin
        name = strip_namespace(topic, self.namespace)
        is_clock = topic in (topics.CLOCK, topics.CLOCK_ORIGIN) and self.sim_time

        def callback(data: bytes) -> None:
            with self._lock:  # callbacks may run concurrently (multi-threaded executors)
                if self.bag is None:
                    return
                if is_clock:
                    feed_clock(self.clock, topic, data)
                    self.clock_heard |= topic == topics.CLOCK
                now = self._stamp()
                if thinned and self.image_period:
                    if now * 1e-9 - self.last_image.get(topic, -1e18) < self.image_period - 1e-6:
                        return
                    self.last_image[topic] = now * 1e-9
                self.bag.write_raw(name, type_name, now, data)
                self.counts[topic] = self.counts.get(topic, 0) + 1

        return callback

    def _stamp(self) -> int:
        """Nanoseconds to log a message received now with."""
        est = self.clock.now(time.monotonic()) if self.sim_time else None
        node_now = int(self.get_clock().now().nanoseconds)
        return node_now if est is None else max(round(est * 1e9), node_now)

    def _give_up(self, exc: OSError) -> None:
        reason = 'disk full' if exc.errno == errno.ENOSPC else f'cannot write the bag: {exc}'
        self.get_logger().error(f'{reason}: closing the bag and stopping')
        with contextlib.suppress(OSError, BagError):
            self._close()
        self.bag = None
        raise SystemExit(f'recorder: {reason}')

    def close(self) -> None:
        with self._lock:
            self._close()

    def _close(self) -> None:
        if self.bag is not None:
            self.bag.close()
            self.get_logger().info(
                f'bag closed: {sum(self.counts.values())} messages on {len(self.counts)} topics'
            )
            self.bag = None


def main(args: list[str] | None = None) -> int:
    return run_node('recorder', RecorderNode, args, on_stop=RecorderNode.close, errors=(BagError,))


if __name__ == '__main__':
    exit_now(main())  # the bag is closed by then: no interpreter teardown (a SIGTERM's 10 s)
