"""The frames behind failed demands: each camera's recorded frame (``<cam>/demand_frame``, PNG)
with what its imager found drawn on it (the fitted ellipse, its status and reason).

A hardware run records the frame every imager measured for a demand (``--record-frames used``,
the default); the report shows those of the demands that did not end ``ok``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from activesurv_recording.bagio import read_bag

STATUS_NAMES = ('OK', 'NOT_FOUND', 'REJECTED', 'NO_IMAGE', 'NO_CAMERA_POSE', 'POSE_FAILED')


def _stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def draw(gray: np.ndarray, obs: Any, title: str) -> np.ndarray:
    """The frame in colour with the observation drawn on it."""
    img = cv2.cvtColor(np.asarray(gray, dtype=np.uint8), cv2.COLOR_GRAY2BGR)
    e = obs.ellipse
    ok = int(obs.status) == 0
    colour = (0, 200, 0) if ok else (0, 0, 255)
    if e.semi_major > 0 and np.isfinite([e.center_x, e.center_y, e.semi_minor]).all():
        cv2.ellipse(
            img,
            (round(e.center_x), round(e.center_y)),
            (max(1, round(e.semi_major)), max(1, round(e.semi_minor))),
            float(np.degrees(e.angle)),
            0.0,
            360.0,
            colour,
            1,
            cv2.LINE_AA,
        )
        cv2.drawMarker(img, (round(e.center_x), round(e.center_y)), colour, cv2.MARKER_CROSS, 8)
    status = STATUS_NAMES[int(obs.status)] if int(obs.status) < len(STATUS_NAMES) else '?'
    lines = [title, f'{status}: {obs.reason}' if obs.reason else status]
    for i, text in enumerate(lines):
        y = 18 + 18 * i
        cv2.putText(img, text[:90], (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3)
        cv2.putText(img, text[:90], (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1)
    return img


def failed_demand_frames(
    bag: Path,
    failed: Sequence[int],
    delays: Mapping[str, float],
    out_dir: Path,
    prefix: str,
) -> list[Path]:
    """Write ``<prefix>_d<demand>_<camera>.png`` for every camera asked for a failed demand
    whose frame the bag holds; returns the files written (none for a bag without frames).

    ``delays``: each camera's exposure delay (s): a frame is stamped that long after the
    exposure instant an observation carries."""
    cameras = sorted(delays)
    wanted = set(failed)
    if not wanted:
        return []
    frames: dict[str, list[tuple[int, Any]]] = {}
    observations: list[Any] = []
    topics = {'/marker_observations'} | {f'/{c}/demand_frame' for c in cameras}
    for m in read_bag(bag, topics):
        if m.topic.endswith('/demand_frame'):
            cam = m.topic.strip('/').split('/')[0]
            frames.setdefault(cam, []).append((_stamp(m.msg), m.msg))
        elif m.topic == '/marker_observations' and int(m.msg.demand_index) in wanted:
            observations.append(m.msg)
    written = []
    for obs in observations:
        stamped = _stamp(obs) + round(1e9 * delays.get(obs.camera_id, 0.0))
        near = [(abs(s - stamped), f) for s, f in frames.get(obs.camera_id, [])]
        if not near or min(d for d, _ in near) > 1_000_000:  # 1 ms
            continue
        frame = min(near, key=lambda df: df[0])[1]
        gray = cv2.imdecode(np.frombuffer(bytes(frame.data), np.uint8), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            continue
        title = f'demand {int(obs.demand_index)}, {obs.camera_id}'
        path = out_dir / f'{prefix}_d{int(obs.demand_index)}_{obs.camera_id}.png'
        cv2.imwrite(str(path), draw(gray, obs, title))
        written.append(path)
    return sorted(written)
