"""The live view, as Foxglove sees it: a plain WebSocket client (``websockets``) that speaks the
Foxglove WebSocket protocol by hand (subprotocol ``foxglove.sdk.v1``: JSON ``serverInfo`` and
``advertise``, our ``subscribe``, binary message data with opcode 1) watches a graph run started
with ``--foxglove PORT``."""

from __future__ import annotations

import asyncio
import json
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from rclpy.serialization import deserialize_message

from activesurv_liveview.live import LiveFilter

pytestmark = pytest.mark.graph  # starts node processes

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


async def _watch(port: int, deadline: float) -> dict[str, Any]:
    import websockets

    seen: dict[str, Any] = {'channels': {}, 'messages': {}, 'server': None}
    while time.monotonic() < deadline:  # the server comes up with the graph
        try:
            ws = await websockets.connect(
                f'ws://127.0.0.1:{port}', subprotocols=['foxglove.sdk.v1'], max_size=None
            )
            break
        except OSError:
            await asyncio.sleep(0.5)
    else:
        raise AssertionError('the live view never listened')
    subscribed: dict[int, str] = {}
    late: dict[str, int] = {}  # /tf_static: subscribed to only once the run is going
    async with ws:
        assert ws.subprotocol == 'foxglove.sdk.v1'
        while time.monotonic() < deadline:
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=1.0)
            except TimeoutError:
                continue
            except websockets.ConnectionClosed:
                break  # the run ended
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg['op'] == 'serverInfo':
                    seen['server'] = msg
                elif msg['op'] == 'advertise':
                    subs = []
                    for ch in msg['channels']:
                        seen['channels'][ch['topic']] = ch
                        if ch['topic'] == '/tf_static':
                            late[ch['topic']] = ch['id']
                        elif ch['topic'] in ('/tf', '/demand_horizon') or ch['topic'].endswith(
                            '/image_raw'
                        ):
                            sid = len(subscribed) + 1
                            subscribed[sid] = ch['topic']
                            subs.append({'id': sid, 'channelId': ch['id']})
                    if subs:
                        await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))
            elif frame[0] == 1:  # message data: subscription id, log time, payload
                sid, log_time = struct.unpack_from('<IQ', frame, 1)
                topic = subscribed[sid]
                seen['messages'].setdefault(topic, []).append((log_time, bytes(frame[13:])))
                if late and len(seen['messages'].get('/tf', ())) >= 5:
                    # A viewer that connects late still gets the latched frame tree.
                    subs = [{'id': len(subscribed) + 1, 'channelId': late.pop('/tf_static')}]
                    subscribed[subs[0]['id']] = '/tf_static'
                    await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))
            done = {'/tf', '/tf_static'} <= set(seen['messages']) and any(
                t.endswith('/image_raw') for t in seen['messages']
            )
            if done and len(seen['messages']['/tf']) > 50:
                break
    return seen


def test_a_graph_run_is_served_to_a_foxglove_client(tmp_path: Path) -> None:
    from sensor_msgs.msg import Image
    from tf2_msgs.msg import TFMessage

    port = _free_port()
    out = tmp_path / 'live'
    proc = subprocess.Popen(
        [ACTIVESURV, 'experiment', '--set', 'A', '--system', 'fast', '--out', str(out),
         '--foxglove', str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        seen = asyncio.run(_watch(port, time.monotonic() + 90.0))
    finally:
        try:
            stdout, stderr = proc.communicate(timeout=300)
        except subprocess.TimeoutExpired:
            proc.kill()  # not left running (its nodes die with it: the parent-death signal)
            proc.communicate()
            raise
    assert proc.returncode == 0, stdout[-2000:] + stderr[-2000:]
    assert seen['server'] is not None
    assert seen['server']['name'] == 'activesurv'
    tf = seen['channels']['/tf']
    assert tf['encoding'] == 'cdr'
    assert tf['schemaName'] == 'tf2_msgs/msg/TFMessage'
    assert tf['schemaEncoding'] == 'ros2msg'
    assert 'geometry_msgs/TransformStamped[] transforms' in tf['schema']
    images = [t for t in seen['channels'] if t.endswith('/image_raw')]
    assert {'/cam1/image_raw', '/cam1/preview/image_raw', '/overhead/image_raw'} <= set(images)
    # Previews are for viewers: they never reach the bag.
    meta = (out / 'bag' / 'metadata.yaml').read_text()
    assert '/cam1/image_raw' in meta
    assert 'preview' not in meta
    # The bytes are the ROS 2 messages themselves: they deserialize as such.
    static = deserialize_message(seen['messages']['/tf_static'][0][1], TFMessage)
    children = {t.child_frame_id for t in static.transforms}
    assert {'cam1_base', 'cam1_optical_frame', 'overhead_optical_frame'} <= children
    img_topic = next(t for t in seen['messages'] if t.endswith('/image_raw'))
    img = deserialize_message(seen['messages'][img_topic][0][1], Image)
    assert img.width > 0
    assert len(img.data) == img.step * img.height
    doc = json.loads((out / 'results.json').read_text())
    assert sum(d['status'] == 'ok' for d in doc['demands']) >= 9


def test_image_thinning_and_topic_selection() -> None:
    f = LiveFilter(image_rate=10.0)
    assert f.wanted('/cam3/image_raw')
    assert f.wanted('/tf_static')
    assert not f.wanted('/activesurv/recorder_status')
    kept = [f.keep('/cam1/image_raw', k / 30.0) for k in range(90)]  # 30 Hz for 3 s
    assert sum(kept) == 30
    assert all(f.keep('/tf', 0.0) for _ in range(5))
    with pytest.raises(ValueError, match='image_rate'):
        LiveFilter(image_rate=-1.0)


def test_the_foxglove_layout_shows_what_the_live_view_serves() -> None:
    import re

    from activesurv_bringup.files import config_path

    layout = json.loads((config_path().parent / 'foxglove_layout.json').read_text())
    panels = layout['configById']

    def leaves(node: Any) -> list[str]:
        if isinstance(node, str):
            return [node]
        return leaves(node['first']) + leaves(node['second'])

    shown = leaves(layout['layout'])
    assert sorted(shown) == sorted(panels)  # every panel placed, none missing
    assert sum(p.startswith('Image!') for p in shown) == 4
    assert any(p.startswith('3D!') for p in shown)
    text = json.dumps(panels)
    topics = set(re.findall(r'"(/[a-z0-9_/]+?)(?:\.|")', text))
    served = LiveFilter()
    assert topics
    assert all(served.wanted(t) for t in topics), [t for t in topics if not served.wanted(t)]


def test_latched_messages_reach_late_subscribers() -> None:
    from activesurv_liveview.live import LatchedCache

    cache = LatchedCache()
    cache.latch('/tf_static', 1)
    cache.remember('/tf_static', b'a')
    cache.remember('/tf_static', b'b')
    cache.remember('/tf', b'x')  # not latched: never kept
    cache.subscribed('/tf', now=0.0)
    assert cache.due(now=1.0) == []
    cache.subscribed('/tf_static', now=1.0)
    assert cache.due(now=1.05) == []  # the server may not route to it yet
    assert cache.due(now=1.1) == [('/tf_static', [b'b'])]
    assert cache.due(now=2.0) == []  # once per subscription
    # Subscribed before anything was kept: due once something is.
    cache.latch('/demand_horizon', 1)
    cache.subscribed('/demand_horizon', now=3.0)
    assert cache.due(now=4.0) == []
    cache.remember('/demand_horizon', b'h')
    assert cache.due(now=4.2) == [('/demand_horizon', [b'h'])]
    with pytest.raises(ValueError, match='depth'):
        cache.latch('/x', 0)
    with pytest.raises(ValueError, match='settle'):
        LatchedCache(settle=float('nan'))
