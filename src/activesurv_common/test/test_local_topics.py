"""In-process delivery between the nodes of one container (``local_topics``)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from activesurv_common.ros import local_topics, qos


def _image(sec: int, frame: str = 'cam1_optical_frame') -> Any:
    from sensor_msgs.msg import Image

    msg = Image()
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, 250_000_000
    msg.header.frame_id = frame
    msg.height, msg.width, msg.step, msg.encoding = 2, 3, 3, 'mono8'
    msg.data = bytes(range(6))
    return msg


def test_a_serialized_header_is_read_as_the_message_has_it() -> None:
    from rclpy.serialization import serialize_message

    msg = _image(12)
    raw = serialize_message(msg)
    assert local_topics.raw_header_key(raw) == local_topics.header_key(msg)
    assert local_topics.header_key(msg) == (12, 250_000_000, 'cam1_optical_frame')
    assert local_topics.raw_header_key(raw[:10]) is None  # too short: handled as usual
    assert local_topics.raw_header_key(raw[:4] + bytes(12)) is None  # no frame id


@pytest.fixture
def enabled() -> Iterator[None]:
    local_topics.enable()
    try:
        yield
    finally:
        local_topics.enable(False)


def test_a_container_hands_a_message_over_in_process_and_once(
    rclpy_context: Any, spin_until: Callable[..., bool], enabled: None
) -> None:
    """The subscriber gets the publisher's own object at once (before it goes over DDS), not
    the DDS copy again; a message of another publisher (not in process) still arrives."""
    from sensor_msgs.msg import Image

    camera = rclpy_context.create_node('local_camera')
    imager = rclpy_context.create_node('local_imager')
    other = rclpy_context.create_node('local_other')
    got: list[Any] = []
    early: list[Any] = []  # subscribed before the local publisher existed: plain rclpy
    try:
        local_topics.subscription(other, Image, '/lt/image_raw', early.append, qos.SENSOR_RELIABLE)
        pub = local_topics.publisher(camera, Image, '/lt/image_raw', qos.SENSOR_RELIABLE)
        local_topics.subscription(imager, Image, '/lt/image_raw', got.append, qos.SENSOR_RELIABLE)
        remote = other.create_publisher(Image, '/lt/image_raw', qos.SENSOR_RELIABLE)
        assert spin_until([camera, imager, other], lambda: pub.get_subscription_count() >= 2)
        first = _image(1)
        pub.publish(first)
        assert got == [first]
        assert got[0] is first
        remote.publish(_image(2))
        assert spin_until([camera, imager, other], lambda: len(got) >= 2)
        end = time.monotonic() + 0.5  # the first one's DDS copy has come by now: dropped
        spin_until([camera, imager, other], lambda: time.monotonic() > end, 2.0)
        assert [m.header.stamp.sec for m in got] == [1, 2]
        assert [m.header.stamp.sec for m in early] == [1, 2]  # over DDS only, each once
        assert early[0] is not first
    finally:
        for node in (camera, imager, other):
            node.destroy_node()


def test_without_a_container_they_are_plain_rclpy(rclpy_context: Any) -> None:
    from sensor_msgs.msg import Image

    node = rclpy_context.create_node('plain_node')
    try:
        pub = local_topics.publisher(node, Image, '/lt/plain', qos.SENSOR_RELIABLE)
        assert not isinstance(pub, local_topics.LocalPublisher)
        got: list[Any] = []
        local_topics.subscription(node, Image, '/lt/plain', got.append, qos.SENSOR_RELIABLE)
        pub.publish(_image(3))
        assert got == []  # only over DDS, on a spin
    finally:
        node.destroy_node()


def test_only_local_takes_the_process_publisher_alone_and_adds_no_reader(
    rclpy_context: Any, spin_until: Callable[..., bool], enabled: None
) -> None:
    """A camera's own stage in its container: the states come in process, and no DDS reader
    is made (the publisher counts none; another process's copy never arrives)."""
    from sensor_msgs.msg import JointState

    stage = rclpy_context.create_node('local_stage')
    camera = rclpy_context.create_node('local_cam')
    other = rclpy_context.create_node('local_other_stage')
    got: list[Any] = []
    try:
        pub = local_topics.publisher(stage, JointState, '/lt/joint_states', qos.STATE)
        local_topics.subscription(
            camera, JointState, '/lt/joint_states', got.append, qos.STATE, only_local=True
        )
        remote = other.create_publisher(JointState, '/lt/joint_states', qos.STATE)
        msg = JointState(name=['rail'], position=[0.1])
        msg.header.stamp.sec = 4
        pub.publish(msg)
        assert got == [msg]
        assert got[0] is msg
        end = time.monotonic() + 0.5
        spin_until([stage, camera, other], lambda: time.monotonic() > end, 2.0)
        assert pub.get_subscription_count() == 0
        assert remote.get_subscription_count() == 0
        assert len(got) == 1
    finally:
        for node in (stage, camera, other):
            node.destroy_node()


def test_publish_together_hands_every_message_over_before_any_goes_over_dds(
    rclpy_context: Any, spin_until: Callable[..., bool], enabled: None
) -> None:
    """A camera's intrinsics and frame: its imager has both, in order, before either DDS copy
    is written; a reader in another process hears both, each once."""
    from sensor_msgs.msg import CameraInfo, Image

    camera = rclpy_context.create_node('together_camera')
    imager = rclpy_context.create_node('together_imager')
    viewer = rclpy_context.create_node('together_viewer')
    steps: list[str] = []
    remote: list[str] = []
    try:
        info_pub = local_topics.publisher(camera, CameraInfo, '/lt/info', qos.SENSOR_RELIABLE)
        image_pub = local_topics.publisher(camera, Image, '/lt/frame', qos.SENSOR_RELIABLE)
        for pub, msg_type, topic in (
            (info_pub, CameraInfo, '/lt/info'),
            (image_pub, Image, '/lt/frame'),
        ):
            name = topic.rsplit('/', 1)[1]
            local_topics.subscription(
                imager,
                msg_type,
                topic,
                lambda m, n=name: steps.append(f'local {n}'),
                qos.SENSOR_RELIABLE,
            )
            viewer.create_subscription(
                msg_type, topic, lambda m, n=name: remote.append(n), qos.SENSOR_RELIABLE
            )
            writer = pub._pub  # the DDS writer: note each write

            def write(msg: Any, n: str = name, w: Any = writer.publish) -> None:
                steps.append(f'dds {n}')
                w(msg)

            writer.publish = write
        assert spin_until(
            [camera, imager, viewer],
            lambda: (
                info_pub.get_subscription_count() >= 2 and image_pub.get_subscription_count() >= 2
            ),
        )
        info = CameraInfo()
        info.header.stamp.sec, info.header.frame_id = 5, 'cam1_optical_frame'
        local_topics.publish_together((info_pub, info), (image_pub, _image(5)))
        assert steps == ['local info', 'local frame', 'dds info', 'dds frame']
        assert spin_until([camera, imager, viewer], lambda: len(remote) >= 2)
        end = time.monotonic() + 0.5
        spin_until([camera, imager, viewer], lambda: time.monotonic() > end, 2.0)
        assert sorted(remote) == ['frame', 'info']
        assert len(steps) == 4  # the imager's own DDS copies were dropped
    finally:
        for node in (camera, imager, viewer):
            node.destroy_node()


def test_publish_together_hands_the_dds_copies_to_later_only_when_taken_in_process(
    rclpy_context: Any, enabled: None
) -> None:
    """A demand frame its imager took in process: the DDS copies (bag, viewers) wait for
    ``later``; a topic nobody in the process takes goes over DDS at once."""
    from sensor_msgs.msg import CameraInfo, Image

    camera = rclpy_context.create_node('later_camera')
    imager = rclpy_context.create_node('later_imager')
    steps: list[str] = []
    waiting: list[Callable[[], None]] = []
    try:
        info_pub = local_topics.publisher(camera, CameraInfo, '/lt2/info', qos.SENSOR_RELIABLE)
        image_pub = local_topics.publisher(camera, Image, '/lt2/frame', qos.SENSOR_RELIABLE)
        alone_pub = local_topics.publisher(camera, Image, '/lt2/alone', qos.SENSOR_RELIABLE)
        for msg_type, topic in ((CameraInfo, '/lt2/info'), (Image, '/lt2/frame')):
            name = topic.rsplit('/', 1)[1]
            local_topics.subscription(
                imager, msg_type, topic, lambda m, n=name: steps.append(f'local {n}'), qos.SENSOR
            )
        for pub in (info_pub, image_pub, alone_pub):
            name = pub.topic_name.rsplit('/', 1)[1]
            pub._pub.publish = lambda msg, n=name: steps.append(f'dds {n}')
        assert info_pub.local_subscriptions() == 1
        assert alone_pub.local_subscriptions() == 0
        info = CameraInfo()
        info.header.stamp.sec, info.header.frame_id = 5, 'cam1_optical_frame'
        local_topics.publish_together(
            (info_pub, info), (image_pub, _image(5)), later=waiting.append
        )
        assert steps == ['local info', 'local frame']
        assert len(waiting) == 1
        waiting.pop()()
        assert steps[2:] == ['dds info', 'dds frame']
        steps.clear()
        local_topics.publish_together(
            (info_pub, info), (alone_pub, _image(6)), later=waiting.append
        )
        assert steps == ['local info', 'dds info', 'dds alone']
        assert not waiting
    finally:
        for node in (camera, imager):
            node.destroy_node()
