"""The ``live_view`` node: the graph's topics over the Foxglove WebSocket protocol.

A Foxglove (or Lichtblick) client on ``ws://HOST:PORT`` sees the run as it happens: camera
images (thinned to ``image_rate``), their marker annotations, the frame tree, dispatch markers,
demand points, estimates, stage states, diagnostics
(:data:`activesurv_liveview.live.DEFAULT_TOPICS`).
Messages are forwarded as they are (CDR) with their ROS 2 definitions as schemas; topics are
picked up as their publishers appear, with the QoS those offer (latched topics arrive too).
The server is foxglove-sdk's (subprotocol ``foxglove.sdk.v1``).

Parameters: see ``config/live_view.yaml``.
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy

from activesurv_common.pacing import Backoff
from activesurv_common.ros import qos
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_liveview.live import DEFAULT_TOPICS, LatchedCache, LiveFilter
from activesurv_recording.bagio import cdr_header, typestore
from activesurv_recording.conversions import message_class, recording_qos

PARAMS = (
    Param('port', 8765, 'WebSocket port', minimum=1),
    Param('host', '127.0.0.1', 'address to listen on (0.0.0.0: every interface)'),
    Param('image_rate', 15.0, 'most images per second per image topic (0: all)', minimum=0.0),
    Param('topics', list(DEFAULT_TOPICS), 'topics to serve (shell patterns)'),
    Param('discovery_period', 1.0, 's between looks for new topics', above=0.0),
    Param(
        'discovery_period_max',
        4.0,
        's between looks that find nothing (doubling; at least discovery_period)',
        above=0.0,
    ),
)


class LiveViewNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        import foxglove

        super().__init__('live_view', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.filter = LiveFilter(list(v['topics']), float(v['image_rate']))
        self.ts = typestore()
        self.channels: dict[str, Any] = {}
        self.latched = LatchedCache()
        self.server = foxglove.start_server(
            name='activesurv',
            host=str(v['host']),
            port=int(v['port']),
            server_listener=_listener(self.latched),
        )
        self.get_logger().info(f'Foxglove live view on ws://{v["host"]}:{self.server.port}')
        # A live view runs for hours beside runs and replays that come and go: while a look
        # finds nothing new the period doubles, and a new topic brings it back (as the
        # recorder's discovery does).
        base, most = float(v['discovery_period']), float(v['discovery_period_max'])
        self._backoff = Backoff(base, max(most, base))
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._discovery = self.create_timer(base, self._look, clock=steady)
        self.create_timer(0.2, self._replay_latched, clock=steady)
        self._discover()

    def _replay_latched(self) -> None:
        # A viewer that subscribes late still gets the latched messages, as a ROS subscriber would.
        for topic, messages in self.latched.due():
            for data in messages:
                self.channels[topic].log(data, log_time=time.time_ns())

    def _look(self) -> None:
        found = self._discover()
        self._discovery.timer_period_ns = int(1e9 * self._backoff.after(found > 0))

    def _discover(self) -> int:
        """Serve the wanted topics that have publishers now; returns how many are new."""
        import foxglove

        new = 0
        for topic, types in self.get_topic_names_and_types():
            if topic in self.channels or not types or not self.filter.wanted(topic):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            type_name = types[0]
            try:
                cls = message_class(type_name)
                definition = self.ts.generate_msgdef(type_name, ros_version=2)[0]
            except (ImportError, AttributeError, ValueError, KeyError) as exc:
                self.get_logger().warning(f'cannot serve {topic} [{type_name}]: {exc}')
                self.channels[topic] = None
                continue
            schema = foxglove.Schema(name=type_name, encoding='ros2msg', data=definition.encode())
            channel = foxglove.Channel(topic, schema=schema, message_encoding='cdr')
            self.channels[topic] = channel
            profile, _ = recording_qos(publishers, qos.published_depth(topic))
            if profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
                self.latched.latch(topic, qos.published_depth(topic) or 1)
            self.create_subscription(cls, topic, self._callback(topic, channel), profile, raw=True)
            self.get_logger().info(f'serving {topic} [{type_name}]')
            new += 1
        return new

    def _callback(self, topic: str, channel: Any) -> Any:
        image = topic.endswith('image_raw')

        def callback(data: bytes) -> None:
            # Images are thinned by their stamps (steady, whatever the transport's jitter).
            try:
                when = cdr_header(bytes(data[:64]))[0] if image else time.monotonic()
            except ValueError:
                when = time.monotonic()
            if self.filter.keep(topic, when):
                channel.log(bytes(data), log_time=time.time_ns())
                self.latched.remember(topic, bytes(data))

        return callback

    def destroy_node(self) -> None:
        self.server.stop()
        super().destroy_node()


def _listener(latched: LatchedCache) -> Any:
    """The server's subscription events (called from its own thread) go to ``latched``."""
    from foxglove.websocket import ServerListener

    class Listener(ServerListener):
        def on_subscribe(self, client: Any, channel: Any) -> None:
            latched.subscribed(str(channel.topic))

    return Listener()


def main(args: list[str] | None = None) -> int:
    return run_node('live_view', LiveViewNode, args, errors=(OSError, RuntimeError))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
