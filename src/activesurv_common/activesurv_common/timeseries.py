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

    A node on simulated time sees the time of the last tick (20 Hz in the graph: up to 50 ms
    behind). A recorder that stamps what it receives, or a latency measured in simulated time,
    needs better. A tick is heard late, never early: by the hop, and by as long as its process
    waits for the CPU (at a demand instant, several milliseconds). So the estimate is fitted
    to the ticks heard earliest (a lower envelope, as a network clock filter does): the rate
    from the earliest-heard tick of the older and of the newer half of the recent ticks, the
    origin from the earliest-heard of the newest ``recent``. A tick heard late then no longer
    makes every reading after it late. It never reads more than ``max_ahead`` simulated
    seconds past the last tick (a paused clock stays paused) and never backwards. A clock
    held (the same time ticked again: paused, or not started yet) or a tick heard
    ``max_late`` wall seconds behind the fit (a pause or a restart) starts the fit over.
    On one host a fit is not needed: :meth:`set_origin` takes the clock owner's own mapping
    (the fit still comes 1-3 ms behind it with 10 Hz ticks on this machine).
    """

    def __init__(
        self, window: int = 200, max_ahead: float = 0.25, recent: int = 50, max_late: float = 0.1
    ) -> None:
        self.window = window
        self.max_ahead = max_ahead
        self.recent = recent
        self.max_late = max_late
        self._ticks: list[tuple[float, float]] = []  # (sim, wall) of the running clock
        self._last_tick: tuple[float, float] | None = None
        self._rate = 1.0
        self._origin: float | None = None  # wall time of simulated 0 at the fitted rate
        self._last = -math.inf
        self._exact: tuple[float, float] | None = None  # the owner's (wall of sim 0, rate)

    def set_origin(self, wall0: float, rate: float) -> None:
        """The clock owner's own mapping, simulated = (wall - ``wall0``) * ``rate``, on the
        same host's steady clock (the simulated xy table publishes it): readings are then
        exact, neither a hop nor a fit behind, before the first tick too (a process that
        stalled at start-up and handles a message before its ticks). A tick ahead of the
        mapping, or 10 s behind it, is from another clock (a bag played with an old mapping):
        the mapping is dropped."""
        if math.isfinite(wall0) and math.isfinite(rate) and rate > 0.0:
            self._exact = (wall0, rate)

    def tick(self, sim: float, wall: float) -> None:
        """A /clock tick at simulated time ``sim``, received at steady wall time ``wall``."""
        if not (math.isfinite(sim) and math.isfinite(wall)):
            return
        if self._exact is not None:
            off = (wall - self._exact[0]) * self._exact[1] - sim
            if not -0.01 <= off <= 10.0:
                self._exact = None
        last = self._last_tick
        self._last_tick = (sim, wall)
        if last is not None and sim < last[0]:
            self._last = -math.inf  # the clock was reset (a new run): start over
            self._exact = None
        if last is None or sim <= last[0]:
            self._restart(sim, wall, held=last is not None and sim == last[0])
            return
        if self._origin is not None and wall - (self._origin + sim / self._rate) > self.max_late:
            self._restart(sim, wall, held=False)
            return
        self._ticks.append((sim, wall))
        del self._ticks[: -self.window]
        self._fit()

    def _restart(self, sim: float, wall: float, held: bool) -> None:
        # A held clock's ticks do not lie on the running clock's line: not fitted.
        self._ticks = [] if held else [(sim, wall)]
        self._origin = None

    def _fit(self) -> None:
        ticks, n = self._ticks, len(self._ticks)
        if n < 2:
            return
        r = self._rate

        def earliest(lo: int, hi: int) -> tuple[float, float]:
            return min(ticks[lo:hi], key=lambda t: t[1] - t[0] / r)

        (s0, w0), (s1, w1) = (
            (earliest(0, n // 2), earliest(n // 2, n))
            if n >= 4
            else (
                ticks[0],
                ticks[-1],
            )
        )
        if w1 > w0 and s1 > s0:
            self._rate = r = (s1 - s0) / (w1 - w0)
        self._origin = min(w - s / r for s, w in ticks[-self.recent :])

    @property
    def rate(self) -> float:
        """Simulated seconds per wall second over the recent ticks (1.0 until known)."""
        return self._rate

    def now(self, wall: float) -> float | None:
        """Simulated time at steady wall time ``wall``; None before the first tick."""
        if self._exact is not None:
            self._last = max(self._last, (wall - self._exact[0]) * self._exact[1])
            return self._last
        if self._last_tick is None:
            return None
        sim, at = self._last_tick
        if self._origin is None:
            fitted = sim + max(wall - at, 0.0) * self._rate
        else:
            fitted = (wall - self._origin) * self._rate
        self._last = max(self._last, min(max(fitted, sim), sim + self.max_ahead))
        return self._last
