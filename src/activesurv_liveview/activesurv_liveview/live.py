"""Which topics the live view serves, and how often (pure core).

The live view forwards the graph's messages unchanged (CDR, with their ROS 2 message
definitions as schemas, as foxglove_bridge does), so Foxglove decodes them with its own ROS 2
readers. Images are paced to ``image_rate`` per topic on average (a browser needs 10-15 Hz,
not 30); everything else passes.
"""

from __future__ import annotations

import fnmatch
import math
import threading
import time
from collections import deque
from collections.abc import Sequence

from activesurv_common.pacing import Pacer

DEFAULT_TOPICS = (
    '/tf',
    '/tf_static',
    '/*/image_raw',
    '/*/preview/image_raw',
    '/*/camera_info',
    '/*/marker_annotations',
    '/*/stage/joint_states',
    '/dispatch_markers',
    '/dispatch_plan',
    '/demand_horizon',
    '/capture_request',
    '/marker_observations',
    '/target_estimate',
    '/target_pose',
    '/object_state',
    '/object_tracks',
    '/object_track_markers',
    '/overhead/track',
    '/overhead/fixes',
    '/diagnostics',
)


class LiveFilter:
    """Topic selection (shell patterns) and image thinning.

    Args:
        patterns: topics to serve (``*`` matches a camera id).
        image_rate: most images per second per image topic (0: all).
    """

    def __init__(self, patterns: Sequence[str] = DEFAULT_TOPICS, image_rate: float = 10.0) -> None:
        if not image_rate >= 0.0:
            raise ValueError(f'image_rate must be >= 0, got {image_rate}')
        self.patterns = tuple(patterns)
        self.image_rate = float(image_rate)
        self._pacers: dict[str, Pacer] = {}
        self.passed = 0
        self.thinned = 0

    def wanted(self, topic: str) -> bool:
        return any(fnmatch.fnmatchcase(topic, p) for p in self.patterns)

    def keep(self, topic: str, now: float) -> bool:
        """Whether a message of ``topic`` arriving at ``now`` (s, steady) goes out."""
        if self.image_rate and topic.endswith('image_raw'):
            # Paced, not cut at a minimum interval: a 10 Hz stream whose frames come with
            # jitter passes whole, a faster one at 10 Hz on average.
            pacer = self._pacers.setdefault(topic, Pacer(self.image_rate))
            if not pacer.ready(now):
                self.thinned += 1
                return False
        self.passed += 1
        return True


class LatchedCache:
    """The last messages of latched (transient-local) topics, for viewers that come late.

    A latched topic (``/tf_static``, ``/demand_horizon``) is published once; the server drops
    what nobody subscribes to, so a viewer that connects later would never see the frame tree.
    As ROS does for a late subscriber, the cache hands the last ``depth`` messages to every new
    subscription: ``settle`` seconds after it (the server reports a subscription from its own
    thread, possibly before it routes messages to it), and, when nothing has been kept yet,
    as soon as the first message is. Thread-safe.
    """

    def __init__(self, settle: float = 0.1) -> None:
        if not math.isfinite(settle) or settle < 0.0:
            raise ValueError(f'settle must be a finite time >= 0 s, got {settle}')
        self.settle = settle
        self._kept: dict[str, deque[bytes]] = {}
        self._pending: dict[str, float] = {}
        self._lock = threading.Lock()

    def latch(self, topic: str, depth: int) -> None:
        """Keep the last ``depth`` messages of ``topic``."""
        if depth < 1:
            raise ValueError(f'depth must be >= 1, got {depth}')
        with self._lock:
            self._kept.setdefault(topic, deque(maxlen=depth))

    def remember(self, topic: str, data: bytes) -> None:
        with self._lock:
            kept = self._kept.get(topic)
            if kept is not None:
                kept.append(data)

    def subscribed(self, topic: str, now: float | None = None) -> None:
        """A viewer subscribed to ``topic`` (monotonic ``now``): its kept messages are due."""
        with self._lock:
            if topic in self._kept:
                self._pending[topic] = time.monotonic() if now is None else now

    def due(self, now: float | None = None) -> list[tuple[str, list[bytes]]]:
        """The kept messages of every topic subscribed to ``settle`` s or more before ``now``.

        A subscription whose topic has kept nothing yet stays due until something is kept.
        """
        t = time.monotonic() if now is None else now
        with self._lock:
            ready = sorted(
                topic
                for topic, since in self._pending.items()
                if self._kept[topic] and t - since >= self.settle
            )
            out = [(topic, list(self._kept[topic])) for topic in ready]
            for topic in ready:
                del self._pending[topic]
        return out
