"""Replay a recorded run: re-run imaging and fusion on its recorded data.

A replay starts fresh imager and fusion nodes (and a recorder for their output) on simulated
time, then republishes the recorded inputs of imaging and fusion: capture requests, every
camera's frames and camera_info, and the stage joint states. The messages go out as the bytes
recorded, on the bag's own clock (``/clock`` follows the bag time, at ``rtf`` times real time).
The new estimates are then compared with the recorded ones. Imaging is deterministic, so a
faithful replay reproduces them.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from activesurv_bringup.errors import BagError
from activesurv_bringup.observer import Observer
from activesurv_bringup.specs import imager_spec, live_view_spec
from activesurv_common.ros.conversions import gray_to_image, sec_to_time
from activesurv_dispatch.sensors import load_setup, setup_from_dict
from activesurv_launch.launcher import Launcher, NodeSpec
from activesurv_launch.session import GraphSession
from activesurv_recording.bagio import offered_qos, read_bag
from activesurv_recording.conversions import message_class, playback_qos
from activesurv_recording.run_record import RunRecord, read_run_record

Progress = Callable[[str], None]


def replay_specs(record: RunRecord, bag: Path) -> list[NodeSpec]:
    # The mounts the run's imagers were given (its calibration), else the paper set-up.
    if record.setup is not None:
        setup = setup_from_dict(record.setup, record.system)
    else:
        setup = load_setup(motion=record.system)
    sim = {'use_sim_time': True}
    specs = [
        NodeSpec(
            'replay_recorder',
            'activesurv_recording.recorder_node',
            parameters={
                **sim,
                'output': str(bag),
                'image_rate': 0.0,
                'run_info': record.as_replay().to_json(),
            },
        )
    ]
    # A hardware run's imagers: their trigger and timing as the run told them (the recorded
    # frames are its demand frames, measured as they were).
    told = record.imagers
    for s in setup.sensors:
        own = dict(told.get(s.camera_id, {}))
        own.pop('camera_id', None)
        optics = dict(record.imager_optics.get(s.camera_id, {}))
        specs.append(
            imager_spec(
                s,
                {
                    'camera_id': s.camera_id,
                    'marker_radius': record.marker_radius,
                    **optics,
                    **own,
                },
                sim_time=True,
                extra={
                    'reliable_images': True,
                    'exact_states': not own,
                    'frame_timeout': max(3.0, float(own.get('frame_timeout', 0.0))),
                },
            )
        )
    specs.append(
        NodeSpec(
            'fusion',
            'activesurv_fusion.fusion_node',
            parameters={
                **sim,
                'collect_timeout': 4.0,
            },
        )
    )
    return specs


def _inputs(record: RunRecord) -> set[str]:
    cams = list(record.initial_poses)
    topics = {'/capture_request'}
    for c in cams:
        topics |= {f'/{c}/image_raw', f'/{c}/camera_info', f'/{c}/stage/joint_states'}
        topics.add(f'/{c}/demand_frame')  # a hardware run's recorded frames (PNG)
    return topics


def _as_image(m: Any) -> tuple[str, Any]:
    """A recorded demand frame (PNG) as the camera's ``image_raw`` message."""
    gray = cv2.imdecode(np.frombuffer(bytes(m.msg.data), np.uint8), cv2.IMREAD_GRAYSCALE)
    if gray is None:
        raise BagError(f'{m.topic}: a frame that is not a PNG image')
    stamp = m.msg.header.stamp
    msg = gray_to_image(gray, str(m.msg.header.frame_id), sec_to_time(0.0))
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(stamp.sec), int(stamp.nanosec)
    return m.topic.removesuffix('/demand_frame') + '/image_raw', msg


def run_replay(
    bag: Path,
    out_dir: Path,
    rtf: float = 1.0,
    progress: Progress = print,
    foxglove: int | None = None,
) -> Path:
    """Replay ``bag``; returns the new bag with the replayed estimates.

    Raises:
        BagError: for an unreadable bag; NodeDiedError if a replay node dies.
    """
    record = read_run_record(bag)
    messages = list(read_bag(bag, _inputs(record)))
    if not messages:
        raise BagError(f'bag {bag} has no imaging inputs to replay')
    out_dir.mkdir(parents=True, exist_ok=True)
    new_bag = out_dir / 'bag'
    specs = replay_specs(record, new_bag)
    if foxglove is not None:
        specs.insert(-1, live_view_spec(foxglove))
    # Each topic is offered with the QoS its publishers offered when it was recorded
    # (``playback_qos``, what ``ros2 bag play`` does), so a bag replays the same way with either.
    # Bags from before the recorder noted offered QoS, or ACTIVESURV_REPLAY_RECORDED_QOS=0,
    # get reliable + transient local (depth 50) on every topic, which matches every subscriber.
    faithful = os.environ.get('ACTIVESURV_REPLAY_RECORDED_QOS', '1') != '0' and record.offered_qos
    recorded = offered_qos(bag) if faithful else {}
    fallback = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=50,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    with Observer('activesurv_replayer') as obs:
        node = obs.node
        pubs: dict[str, Any] = {}
        for m in messages:
            if m.topic.endswith('/demand_frame'):
                image_topic = m.topic.removesuffix('/demand_frame') + '/image_raw'
                if image_topic not in pubs:
                    pubs[image_topic] = node.create_publisher(
                        message_class('sensor_msgs/msg/Image'), image_topic, fallback
                    )
            elif m.topic not in pubs:
                qos = playback_qos(recorded.get(m.topic, []), fallback)
                pubs[m.topic] = node.create_publisher(message_class(m.msgtype), m.topic, qos)
        clock_pub = node.create_publisher(Clock, '/clock', QoSProfile(depth=1))
        launcher = Launcher(specs, workdir=out_dir / 'logs', env=dict(os.environ))

        def clock(t_ns: int) -> None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(int(t_ns), 1_000_000_000)
            clock_pub.publish(msg)

        names = {s.name for s in specs}
        with GraphSession(
            launcher,
            specs,
            lambda: obs.missing(names),
            obs.spin,
            settle=0.0,
            trap_signals=False,  # Ctrl-C ends a replay at once: nothing to finish
        ) as graph:
            _play(
                graph, node, pubs, clock_pub, clock, obs.spin, messages, rtf, progress, faithful,
                names,
            )  # fmt: skip
    return new_bag


def _play(
    graph: GraphSession,
    node: Any,
    pubs: dict[str, Any],
    clock_pub: Any,
    clock: Callable[[int], None],
    spin: Callable[[float], None],
    messages: list[Any],
    rtf: float,
    progress: Progress,
    faithful: bool,
    names: set[str],
) -> None:
    """Publish the recorded inputs on the bag's clock (``clock(t_ns)`` sets /clock), once
    every subscriber is matched (``names``: the replay's nodes)."""
    # Every subscriber must be matched before the first message: the imagers subscribe
    # volatile, so a message sent before the match is lost to them (a camera's first
    # demand then measured with a held, wrong stage state, or not at all). Matched means
    # the replay's own readers of each topic discovered (the recorder's alone is not enough)
    # and every discovered reader matched.
    everyone = [*pubs.items(), ('/clock', clock_pub)]
    imagers = {n for n in names if n.endswith('_imager')}

    def readers(topic: str) -> set[str]:
        """The replay's nodes that must hear ``topic`` before it is played."""
        if topic == '/capture_request':
            return imagers | ({'fusion'} & names)
        own = f'{topic.split("/")[1]}_imager'
        return {own} if own in imagers else set()

    def matched() -> bool:
        for topic, pub in everyone:
            infos = node.get_subscriptions_info_by_topic(topic)
            if not readers(topic) <= {i.node_name for i in infos}:
                return False
            if not infos or pub.get_subscription_count() < len(infos):
                return False
        return True

    deadline = time.monotonic() + 20.0
    while not matched() and time.monotonic() < deadline:
        graph.check()
        spin(0.05)
    settle = time.monotonic() + 0.5
    while time.monotonic() < settle:  # and the subscribers matched back
        spin(0.05)
    how = 'the recorded QoS' if faithful else 'reliable + transient local QoS'
    progress(f'replaying {len(messages)} messages into {len(names)} nodes with {how}')
    t0_bag = messages[0].t_ns
    t0_wall = time.monotonic()
    last_clock = 0
    for m in messages:
        due = t0_wall + (m.t_ns - t0_bag) * 1e-9 / rtf
        while time.monotonic() < due:
            spin(max(0.0, min(0.01, due - time.monotonic())))
        if m.t_ns - last_clock > 10_000_000:
            clock(m.t_ns)
            last_clock = m.t_ns
        if m.topic.endswith('/demand_frame'):
            topic, image = _as_image(m)
            pubs[topic].publish(image)
        else:
            pubs[m.topic].publish(m.raw)
    # Keep time running so that the last demands reach their fusion deadlines.
    end = messages[-1].t_ns + 3_000_000_000
    t = messages[-1].t_ns
    while t < end:
        graph.check()
        t += 20_000_000
        clock(t)
        spin(0.02 / rtf)


def compare(original: Path, replayed: Path) -> list[dict[str, Any]]:
    """Per demand: the recorded and the replayed estimate and how far apart they are."""

    def estimates(bag: Path) -> dict[int, Any]:
        out: dict[int, Any] = {}
        for m in read_bag(bag, {'/target_estimate'}):
            out.setdefault(int(m.msg.demand_index), m.msg)
        return out

    a, b = estimates(original), estimates(replayed)
    rows = []
    for j in sorted(set(a) | set(b)):
        ea, eb = a.get(j), b.get(j)
        diff = math.nan
        if ea is not None and eb is not None:
            pa = np.array([ea.position.x, ea.position.y, ea.position.z])
            pb = np.array([eb.position.x, eb.position.y, eb.position.z])
            if np.all(np.isfinite(pa)) and np.all(np.isfinite(pb)):
                diff = float(np.linalg.norm(pa - pb))
        rows.append(
            {
                'index': j,
                'recorded_status': None if ea is None else int(ea.status),
                'replayed_status': None if eb is None else int(eb.status),
                'position_difference': diff,
                'recorded_cameras': [] if ea is None else list(ea.cameras_used),
                'replayed_cameras': [] if eb is None else list(eb.cameras_used),
            }
        )
    return rows
