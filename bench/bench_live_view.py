"""The live view at rtf 1 (``live_view.*``): a Foxglove client watching a graph run.

``activesurv experiment --set A --system fast --seed 7 --calibration truth --foxglove PORT`` at
rtf 1, watched by a plain WebSocket client (``foxglove.sdk.v1``) subscribed to every channel
the server advertises, ``runs`` times:

* ``image_hz``: per image topic, messages per wall second over the middle half of the run
  ((n - 1) / span of the arrivals inside it; the worst run); ``image_hz_min`` over the cameras'
  preview streams and the overhead images (the demand frames ``<cam>/image_raw`` come once
  per demand and are not a stream);
* ``overhead_hz_by_stamp``: the overhead images per second of their own stamps (sim time) over
  the same window, and ``overhead_frames_dropped``: frames missing from the client's sequence
  (a stamp gap over 1.5 intervals), both the worst run: the overhead camera is a 10 Hz camera,
  so at an rtf a hair under 1 its wall rate is a hair under 10 with every frame shown;
* ``demands_ok``: demands answered ``ok`` (worst run);
* ``cores_with`` / ``cores_without``: CPU cores of the whole run (``cpu.json``) with the live
  view and its previews, and of the same run without ``--foxglove``; ``live_view_cores``: the
  live-view process alone.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

RUNS = int(os.environ.get('ACTIVESURV_BENCH_RUNS', '2'))
ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')


def _port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


async def _watch(port: int, deadline: float) -> tuple[dict[str, list[float]], list[float]]:
    """Arrival times (monotonic) of every message, per topic, and the overhead images'
    header stamps (s), until the server goes."""
    import websockets

    while True:
        try:
            ws = await websockets.connect(
                f'ws://127.0.0.1:{port}', subprotocols=['foxglove.sdk.v1'], max_size=None
            )
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.3)
    topics: dict[int, str] = {}
    arrivals: dict[str, list[float]] = {}
    stamps: list[float] = []
    async with ws:
        while time.monotonic() < deadline:
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=1.0)
            except TimeoutError:
                continue
            except websockets.ConnectionClosed:
                break
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg['op'] == 'advertise':
                    subs = []
                    for ch in msg['channels']:
                        topics[len(topics) + 1] = ch['topic']
                        subs.append({'id': len(topics), 'channelId': ch['id']})
                    await ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))
            elif frame[0] == 1:
                sid = struct.unpack_from('<I', frame, 1)[0]
                arrivals.setdefault(topics[sid], []).append(time.monotonic())
                if topics[sid] == '/overhead/image_raw':
                    # op, subscription, log time, then the CDR message: its encapsulation
                    # header and the header stamp (sec, nanosec) come first
                    sec, nsec = struct.unpack_from('<iI', frame, 1 + 4 + 8 + 4)
                    stamps.append(sec + 1e-9 * nsec)
    return arrivals, stamps


def _middle(values: list[float]) -> list[float]:
    a = values[0] + 0.25 * (values[-1] - values[0])
    b = values[0] + 0.75 * (values[-1] - values[0])
    return [v for v in values if a <= v <= b]


def _by_stamp(stamps: list[float]) -> tuple[float, int]:
    """Frames per stamp second over the middle half, and frames missing from the sequence."""
    inside = _middle(sorted(stamps))
    if len(inside) < 3:
        return 0.0, 0
    gaps = [b - a for a, b in itertools.pairwise(inside)]
    step = sorted(gaps)[len(gaps) // 2]
    dropped = sum(round(g / step) - 1 for g in gaps if g > 1.5 * step)
    return round((len(inside) - 1) / (inside[-1] - inside[0]), 2), dropped


def _rates(arrivals: dict[str, list[float]]) -> dict[str, float]:
    images = {k: v for k, v in arrivals.items() if k.endswith('image_raw') and len(v) > 1}
    t0 = min(v[0] for v in images.values())
    t1 = max(v[-1] for v in images.values())
    a, b = t0 + 0.25 * (t1 - t0), t0 + 0.75 * (t1 - t0)
    out = {}
    for topic, ts in sorted(images.items()):
        inside = [t for t in ts if a <= t <= b]
        span = inside[-1] - inside[0] if len(inside) > 1 else 0.0
        out[topic] = round((len(inside) - 1) / span, 2) if span > 0 else 0.0
    return out


def _experiment(out: Path, port: int | None) -> subprocess.Popen[str]:
    cmd = [ACTIVESURV, 'experiment', '--set', 'A', '--system', 'fast', '--seed', '7',
           '--calibration', 'truth', '--out', str(out)]  # fmt: skip
    if port is not None:
        cmd += ['--foxglove', str(port)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _finish(proc: subprocess.Popen[str], out: Path) -> tuple[int, dict[str, Any]]:
    log, _ = proc.communicate(timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f'experiment failed:\n{log[-2000:]}')
    doc = json.loads((out / 'results.json').read_text())
    ok = sum(d['status'] == 'ok' for d in doc['demands'])
    return ok, json.loads((out / 'cpu.json').read_text())


def run() -> dict[str, Any]:
    hz: dict[str, float] = {}
    oks, cores, view = [], [], []
    by_stamp: list[tuple[float, int]] = []
    with tempfile.TemporaryDirectory(prefix='activesurv-bench-live-') as tmp:
        for i in range(RUNS):
            port, out = _port(), Path(tmp) / f'live{i}'
            proc = _experiment(out, port)
            arrivals, stamps = asyncio.run(_watch(port, time.monotonic() + 300.0))
            ok, cpu = _finish(proc, out)
            by_stamp.append(_by_stamp(stamps))
            for topic, rate in _rates(arrivals).items():
                hz[topic] = min(rate, hz.get(topic, rate))
            oks.append(ok)
            cores.append(cpu['cores'])
            view.append(cpu['cpu_seconds']['/live_view'] / cpu['wall_seconds'])
        out = Path(tmp) / 'plain'
        _, plain = _finish(_experiment(out, None), out)
    streams = [v for k, v in hz.items() if '/preview/' in k or k.startswith('/overhead/')]
    return {
        'runs': RUNS,
        'image_hz': hz,
        'image_hz_min': min(streams),
        'overhead_hz_by_stamp': min(r for r, _ in by_stamp),
        'overhead_frames_dropped': max(d for _, d in by_stamp),
        'demands_ok': f'{min(oks)}/10',
        'cores_with': round(max(cores), 3),
        'cores_without': plain['cores'],
        'live_view_cores': round(max(view), 3),
    }
