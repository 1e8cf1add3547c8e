"""The QoS a recorder notes for a topic and the QoS a replay offers again (no ROS graph)."""

from __future__ import annotations

from types import SimpleNamespace

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from activesurv_common.ros import qos
from activesurv_recording.conversions import playback_qos, recording_qos


def _pub(profile: QoSProfile) -> SimpleNamespace:
    return SimpleNamespace(qos_profile=profile)


def test_latched_publishers_are_recorded_and_replayed_latched_with_their_depth() -> None:
    sub, offered = recording_qos([_pub(qos.EVENTS_LATCHED), _pub(qos.EVENTS_LATCHED)])
    assert sub.reliability == ReliabilityPolicy.RELIABLE
    assert sub.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert [q.depth for q in offered] == [50, 50]
    play = playback_qos(offered, None)
    assert play.reliability == ReliabilityPolicy.RELIABLE
    assert play.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert play.depth == 50


def test_one_best_effort_publisher_makes_the_topic_best_effort() -> None:
    sensor = QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=5, reliability=ReliabilityPolicy.BEST_EFFORT
    )
    sub, offered = recording_qos([_pub(qos.STATE), _pub(sensor)])
    assert sub.reliability == ReliabilityPolicy.BEST_EFFORT  # else it would miss one of them
    assert sub.durability == DurabilityPolicy.VOLATILE
    play = playback_qos(offered, None)
    assert play.reliability == ReliabilityPolicy.BEST_EFFORT
    assert play.depth == 20


def test_a_bag_without_recorded_qos_replays_with_the_fallback() -> None:
    fallback = QoSProfile(depth=7)
    assert playback_qos([], fallback) is fallback
