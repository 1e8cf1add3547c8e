"""In-process delivery between the nodes of one container, as rclcpp's intra-process comms.

rclpy has no intra-process delivery: a message between two nodes of one process is serialized,
handed through the DDS participant, woken up for on the executor and deserialized again. For a
camera's frames that is the step between the exposure and its imaging (0.5-5 ms at a demand
instant on two cores, docs/performance.md). A container that spins its members on one thread
calls :func:`enable`; then a :func:`publisher` first calls the callbacks of the
:func:`subscription` s of the same resolved topic in the process, with the message object
itself, and then publishes it over DDS for everyone else (the recorder, viewers). A
subscription takes messages in process when its topic's publisher was made before it in the
process (the graph builds a camera before its imager); it then also hears the DDS copy (taken
raw, not deserialized): a message whose header it has had in process is dropped, any other
(another process's publisher) is handled as usual. Any other subscription (a driver in
another process, a rig's camera) is a plain rclpy one. Without :func:`enable` (a node alone,
a multi-threaded composition, where a direct call would bypass the node's callback group) both
are plain rclpy publishers and subscriptions.

Only messages that begin with a ``std_msgs/Header`` (stamp and frame id) may use it.
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message

_ENABLED = [False]
_SUBSCRIBERS: dict[str, list[Callable[[Any], None]]] = {}
_PUBLISHERS: set[str] = set()  # resolved topics with a local publisher in this process
_KEPT = 32  # header keys remembered per subscription (frames in flight over DDS)


def enable(on: bool = True) -> None:
    """Deliver in process from now on (call before the nodes are built)."""
    _ENABLED[0] = on


def header_key(msg: Any) -> tuple[int, int, str]:
    """A message's identity: its header's stamp and frame id."""
    h = msg.header
    return int(h.stamp.sec), int(h.stamp.nanosec), str(h.frame_id)


def raw_header_key(raw: bytes) -> tuple[int, int, str] | None:
    """:func:`header_key` read off a serialized (CDR) message, or None if it cannot be."""
    if len(raw) < 16:
        return None
    order = '<' if raw[1] & 1 else '>'  # encapsulation: CDR_LE (0x0001) or CDR_BE (0x0000)
    sec, nanosec, size = struct.unpack_from(order + 'iII', raw, 4)
    if size < 1 or 16 + size > len(raw):
        return None
    return sec, nanosec, raw[16 : 16 + size - 1].decode('utf-8', 'replace')


class LocalPublisher:
    """Publishes to the process's subscriptions of its topic first, then over DDS."""

    def __init__(self, node: Node, msg_type: Any, topic: str, qos_profile: QoSProfile) -> None:
        self._pub = node.create_publisher(msg_type, topic, qos_profile)
        self.topic_name = self._pub.topic_name
        _PUBLISHERS.add(self.topic_name)

    def publish(self, msg: Any) -> None:
        self.publish_local(msg)
        self._pub.publish(msg)

    def publish_local(self, msg: Any) -> None:
        """To this process's subscriptions of the topic only."""
        for callback in list(_SUBSCRIBERS.get(self.topic_name, ())):
            callback(msg)

    def publish_remote(self, msg: Any) -> None:
        """Over DDS only."""
        self._pub.publish(msg)

    def local_subscriptions(self) -> int:
        """The subscriptions of this process that take the topic in process."""
        return len(_SUBSCRIBERS.get(self.topic_name, ()))

    def get_subscription_count(self) -> int:
        return int(self._pub.get_subscription_count())


def publisher(node: Node, msg_type: Any, topic: str, qos_profile: QoSProfile) -> Any:
    """A publisher that delivers in process first when :func:`enable` d, else rclpy's."""
    if not _ENABLED[0]:
        return node.create_publisher(msg_type, topic, qos_profile)
    return LocalPublisher(node, msg_type, topic, qos_profile)


def publish_together(
    *items: tuple[Any, Any], later: Callable[[Callable[[], None]], None] | None = None
) -> None:
    """Publish each ``(publisher, message)`` in process first, all in order, then over DDS:
    the process's consumers act on them all (a camera's imager on its intrinsics and its
    frame) before any DDS copy is made. Plain rclpy publishers publish in the second pass.

    ``later`` (a :class:`~activesurv_common.ros.deferred.Deferred`): when every topic has
    been taken in process, the DDS pass is handed to it (the copies are then for the bag and
    the viewers, off the instant's critical path); otherwise it runs now.
    """
    for pub, msg in items:
        if isinstance(pub, LocalPublisher):
            pub.publish_local(msg)

    def remote() -> None:
        for pub, msg in items:
            (pub.publish_remote if isinstance(pub, LocalPublisher) else pub.publish)(msg)

    if later is not None and all(
        isinstance(pub, LocalPublisher) and pub.local_subscriptions() for pub, _ in items
    ):
        later(remote)
    else:
        remote()


def subscription(
    node: Node,
    msg_type: Any,
    topic: str,
    callback: Callable[[Any], None],
    qos_profile: QoSProfile,
    only_local: bool = False,
) -> None:
    """Subscribe ``callback``: in process too, each message once, if the topic has a local
    publisher already (and :func:`enable` was called); else as rclpy does.

    ``only_local``: for a topic that has one publisher by design (a camera's own stage in its
    container), take it only in process then: no DDS reader, so the publisher sends one copy
    less and this process wakes once less per message.
    """
    resolved = node.resolve_topic_name(topic)
    if not _ENABLED[0] or resolved not in _PUBLISHERS:
        node.create_subscription(msg_type, topic, callback, qos_profile)
        return
    if only_local:
        _SUBSCRIBERS.setdefault(resolved, []).append(callback)
        return
    seen: deque[tuple[int, int, str]] = deque(maxlen=_KEPT)

    def local(msg: Any) -> None:
        seen.append(header_key(msg))
        callback(msg)

    def remote(raw: bytes) -> None:
        key = raw_header_key(raw)
        if key is not None and key in seen:
            return  # had it in process already
        callback(deserialize_message(raw, msg_type))

    sub = node.create_subscription(msg_type, topic, remote, qos_profile, raw=True)
    _SUBSCRIBERS.setdefault(sub.topic_name, []).append(local)
