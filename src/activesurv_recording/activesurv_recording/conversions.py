"""What the recorder, replay and the live view need from rclpy and the message packages: message
classes by type name, and the QoS to subscribe to and to replay a recorded topic with. The bag
core (:mod:`activesurv_recording.bagio`) stays free of rclpy."""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosbags.rosbag2.metadata import (  # type: ignore[attr-defined]
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from activesurv_common.ros import topics
from activesurv_common.timeseries import ClockEstimate


def feed_clock(clock: ClockEstimate, topic: str, data: bytes) -> None:
    """A serialized /clock tick heard now, or the simulated clock's origin, into ``clock``."""
    if topic == topics.CLOCK:
        c = deserialize_message(data, Clock).clock
        clock.tick(c.sec + 1e-9 * c.nanosec, time.monotonic())
    elif topic == topics.CLOCK_ORIGIN:
        origin = deserialize_message(data, Float64MultiArray).data
        if len(origin) >= 2:
            clock.set_origin(float(origin[0]), float(origin[1]))


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Name`` (the message package must be importable)."""
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def playback_qos(recorded: Sequence[Any], fallback: Any) -> Any:
    """The QoS to publish a recorded topic with, as ``ros2 bag play`` chooses it: reliable and
    transient local only if every recorded publisher was, as deep as the deepest one."""

    if not recorded:
        return fallback
    reliable = all(q.reliability == QosReliability.RELIABLE for q in recorded)
    latched = all(q.durability == QosDurability.TRANSIENT_LOCAL for q in recorded)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(1, *(int(q.depth) for q in recorded)),
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def recording_qos(publishers: Sequence[Any], depth: int | None = None) -> tuple[Any, list[Any]]:
    """How to subscribe to a topic with these publishers (rclpy ``TopicEndpointInfo``), and the
    QoS profiles they offer, for the bag's metadata (what ``ros2 bag play`` offers again).

    The subscription is reliable only if they all are, transient local only if they all are
    (so latched blackboard topics arrive too), and deep enough for their history. Discovery
    does not tell a publisher's depth (it reports 0); ``depth`` (the graph's contract, see
    ``activesurv_common.ros.qos.PUBLISHED``) fills it in, else 10, the rclpy default.
    """

    reliable = bool(publishers) and all(
        i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in publishers
    )
    latched = bool(publishers) and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in publishers
    )
    profile = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max([200, *(int(i.qos_profile.depth) for i in publishers)]),
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )
    zero = QosTime(0, 0)
    offered = []
    for i in publishers:
        q = i.qos_profile
        keep_all = q.history == HistoryPolicy.KEEP_ALL
        offered.append(
            Qos(
                QosHistory.KEEP_ALL if keep_all else QosHistory.KEEP_LAST,
                int(q.depth) or depth or 10,
                QosReliability.RELIABLE
                if q.reliability == ReliabilityPolicy.RELIABLE
                else QosReliability.BEST_EFFORT,
                QosDurability.TRANSIENT_LOCAL
                if q.durability == DurabilityPolicy.TRANSIENT_LOCAL
                else QosDurability.VOLATILE,
                zero,
                zero,
                QosLiveliness.AUTOMATIC,
                zero,
                False,
            )
        )
    return profile, offered
