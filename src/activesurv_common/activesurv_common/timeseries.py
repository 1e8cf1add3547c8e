"""Time-stamped samples with interpolation (object states, joint states, frames)."""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

T = TypeVar('T')


class TimeSeries:
    """A bounded history of vector samples; linear interpolation between them.

    Samples may arrive slightly out of order (they are kept sorted); non-finite samples are
    refused.
    """

    def __init__(self, dim: int, capacity: int = 2000) -> None:
        self.dim = dim
        self.capacity = capacity
        self._t: list[float] = []
        self._v: list[NDArray[np.float64]] = []

    def __len__(self) -> int:
        return len(self._t)

    @property
    def latest_time(self) -> float | None:
        return self._t[-1] if self._t else None

    def add(self, t: float, value: ArrayLike) -> bool:
        """Add a sample; returns False (and ignores it) if it is not finite or wrong-sized."""
        v = np.asarray(value, dtype=np.float64).reshape(-1)
        if v.shape != (self.dim,) or not math.isfinite(t) or not np.all(np.isfinite(v)):
            return False
        i = bisect.bisect_right(self._t, t)
        if i > 0 and self._t[i - 1] == t:
            self._v[i - 1] = v
            return True
        self._t.insert(i, t)
        self._v.insert(i, v)
        if len(self._t) > self.capacity:
            del self._t[0]
            del self._v[0]
        return True

    def has(self, t: float) -> bool:
        """A sample stamped exactly ``t`` is held."""
        i = bisect.bisect_left(self._t, t)
        return i < len(self._t) and self._t[i] == t

    def at(
        self, t: float, hold: float = 0.0, extrapolate: bool = False, max_rate: float = math.inf
    ) -> NDArray[np.float64] | None:
        """The value at ``t``: interpolated between the samples around it, or, if ``t`` is
        outside the history by at most ``hold`` seconds, the nearest sample (``extrapolate``:
        past the newest sample, the line through the last two, unless a component changes
        faster than ``max_rate`` per second there: a jump, not a motion); otherwise None."""
        if not self._t or not math.isfinite(t):
            return None
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            return self._v[i].copy()
        if 0 < i < len(self._t):
            t0, t1 = self._t[i - 1], self._t[i]
            w = (t - t0) / (t1 - t0)
            return np.asarray((1.0 - w) * self._v[i - 1] + w * self._v[i], dtype=np.float64)
        j = 0 if i == 0 else len(self._t) - 1
        if abs(self._t[j] - t) > hold:
            return None
        if extrapolate and i == len(self._t) and len(self._t) >= 2:
            t0, t1 = self._t[-2], self._t[-1]
            rate = (self._v[-1] - self._v[-2]) / (t1 - t0)
            if np.all(np.abs(rate) <= max_rate):
                return np.asarray(self._v[-1] + rate * (t - t1), dtype=np.float64)
        return self._v[j].copy()


class FrameBuffer(Generic[T]):
    """The last few frames (any payload) by stamp; look up the one closest to a time."""

    def __init__(self, capacity: int = 30) -> None:
        self.capacity = capacity
        self._t: list[float] = []
        self._f: list[T] = []

    def __len__(self) -> int:
        return len(self._t)

    def add(self, t: float, frame: T) -> None:
        i = bisect.bisect_right(self._t, t)
        self._t.insert(i, t)
        self._f.insert(i, frame)
        if len(self._t) > self.capacity:
            del self._t[0]
            del self._f[0]

    def closest(self, t: float, tolerance: float) -> tuple[float, T] | None:
        if not self._t:
            return None
        i = bisect.bisect_left(self._t, t)
        best = min(
            (j for j in (i - 1, i) if 0 <= j < len(self._t)), key=lambda j: abs(self._t[j] - t)
        )
        return (self._t[best], self._f[best]) if abs(self._t[best] - t) <= tolerance else None

    def stamps(self) -> Sequence[float]:
        return tuple(self._t)


class ClockEstimate:
    """Simulated time between the ticks of ``/clock``, read off a steady wall clock.

    A node on simulated time sees the time of the last tick (50 Hz: up to 20 ms behind). A
    recorder that stamps what it receives, or a latency measured in simulated time, needs
    better: this extrapolates from the last tick at the rate the recent ticks ran (the real
    time factor), never more than ``max_ahead`` simulated seconds past it (a paused clock
    stays paused) and never backwards.
    """

    def __init__(self, window: int = 50, max_ahead: float = 0.25) -> None:
        self.window = window
        self.max_ahead = max_ahead
        self._ticks: list[tuple[float, float]] = []
        self._last = -math.inf

    def tick(self, sim: float, wall: float) -> None:
        """A /clock tick at simulated time ``sim``, received at steady wall time ``wall``."""
        if not (math.isfinite(sim) and math.isfinite(wall)):
            return
        if self._ticks and sim < self._ticks[-1][0]:
            self._ticks.clear()  # the clock was reset (a new run): start over
            self._last = -math.inf
        self._ticks.append((sim, wall))
        del self._ticks[: -self.window]

    @property
    def rate(self) -> float:
        """Simulated seconds per wall second over the recent ticks (1.0 until known)."""
        if len(self._ticks) < 2:
            return 1.0
        (s0, w0), (s1, w1) = self._ticks[0], self._ticks[-1]
        return (s1 - s0) / (w1 - w0) if w1 > w0 and s1 > s0 else 1.0

    def now(self, wall: float) -> float | None:
        """Simulated time at steady wall time ``wall``; None before the first tick."""
        if not self._ticks:
            return None
        sim, at = self._ticks[-1]
        ahead = min(max(wall - at, 0.0) * self.rate, self.max_ahead)
        self._last = max(self._last, sim + ahead)
        return self._last
