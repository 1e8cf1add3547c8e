"""Pacing a stream of events to a rate, whatever the jitter of their arrival (pure core).

A periodic timer that is late drops its tick: a 10 Hz preview in a busy process came out at
7-9 Hz. A :class:`Pacer` is a token bucket instead: it earns ``rate`` tokens per second of the
caller's clock (wall or stamps), holds at most ``burst``, and lets an event through when it has
a whole token. Fed by events that come more often than ``rate`` (object states at 20 Hz for a
10 Hz preview), it lets through ``rate`` per second on average; a late event is made up for by
the next one.
"""

from __future__ import annotations

import math

from activesurv_common.errors import CommonError


class Pacer:
    """Token bucket: on average ``rate`` events per second pass, bursts of up to ``burst``.

    Args:
        rate: events per second (> 0).
        burst: most tokens held (>= 1); 2 lets one late event be made up for.
    """

    def __init__(self, rate: float, burst: float = 2.0) -> None:
        if not (math.isfinite(rate) and rate > 0.0):
            raise CommonError(f'rate must be finite and > 0, got {rate}')
        if not (math.isfinite(burst) and burst >= 1.0):
            raise CommonError(f'burst must be finite and >= 1, got {burst}')
        self.rate = float(rate)
        self.burst = float(burst)
        self._tokens = 1.0
        self._last: float | None = None

    def ready(self, now: float) -> bool:
        """Whether an event at ``now`` (s, any monotonic clock) goes through (and pay for it)."""
        if self._last is not None:
            self._tokens = min(self.burst, self._tokens + max(0.0, now - self._last) * self.rate)
        self._last = now if self._last is None else max(self._last, now)
        if self._tokens >= 1.0 - 1e-6:
            self._tokens -= 1.0
            return True
        return False


class PhaseLock:
    """Events on a fixed grid of a stream's own stamps: the first event in each period, the
    periods starting ``early`` of a period before ``phase + n / rate``. Fed object states at
    20 Hz, a 10 Hz stream with ``phase`` 0.05 s takes those stamped 0.05, 0.15, ... s (one
    that is missing is made up for by the next state), whatever the stamp of the first: the
    frames of a run fall at the same instants every time (a :class:`Pacer` takes its phase from
    the first event's stamp).

    Args:
        rate: events per second (> 0).
        phase: s, the grid's offset (any finite value).
        early: fraction of a period before a grid instant that counts as it (jitter), in
            [0, 1).
    """

    def __init__(self, rate: float, phase: float = 0.0, early: float = 0.25) -> None:
        if not (math.isfinite(rate) and rate > 0.0):
            raise CommonError(f'rate must be finite and > 0, got {rate}')
        if not math.isfinite(phase):
            raise CommonError(f'phase must be finite, got {phase}')
        if not (math.isfinite(early) and 0.0 <= early < 1.0):
            raise CommonError(f'early must be in [0, 1), got {early}')
        self.rate, self.phase, self.early = float(rate), float(phase), float(early)
        self._last: int | None = None

    def ready(self, t: float) -> bool:
        """Whether an event stamped ``t`` is the first of its period (and take it)."""
        n = math.floor((t - self.phase) * self.rate + self.early)
        if self._last is not None and n <= self._last:
            return False
        self._last = n
        return True


class ExposureClock:
    """A free-running camera's exposures: ``phase + n / rate``, every one of them.

    A camera's sensor clock does not skip an exposure because the host that reads it out was
    busy; a periodic timer in a busy process does (a lab camera's timer at 30 Hz exposed at
    28 Hz, and the exposures it lost fell where the graph was busiest: at demand instants).
    :meth:`due` returns every exposure since the last call, on the grid, however late the call.
    After a stall longer than ``max_late`` (a process stopped in a debugger) the older ones are
    counted in :attr:`lost` instead: a camera's buffer overflows too.

    Args:
        rate: exposures per second (> 0).
        phase: s, the first exposure (any finite value).
        max_late: s, the oldest exposure one call returns (> 0).
    """

    def __init__(self, rate: float, phase: float, max_late: float = 1.0) -> None:
        if not (math.isfinite(rate) and rate > 0.0):
            raise CommonError(f'rate must be finite and > 0, got {rate}')
        if not math.isfinite(phase):
            raise CommonError(f'phase must be finite, got {phase}')
        if not (math.isfinite(max_late) and max_late > 0.0):
            raise CommonError(f'max_late must be finite and > 0, got {max_late}')
        self.rate, self.phase, self.max_late = float(rate), float(phase), float(max_late)
        self._next = 0  # the index of the next exposure
        self.lost = 0

    def due(self, now: float) -> list[float]:
        """The exposures at or before ``now`` not returned yet, oldest first."""
        last = math.floor((now - self.phase) * self.rate + 1e-9)
        if last < self._next:
            return []
        oldest = max(self._next, math.ceil((now - self.max_late - self.phase) * self.rate))
        self.lost += oldest - self._next
        self._next = last + 1
        return [self.phase + n / self.rate for n in range(oldest, last + 1)]


class Backoff:
    """A poll's period: ``base`` while the polls find something, doubling up to ``maximum``
    while they find nothing. A recorder's topic discovery costs 1-5 ms of CPU on this machine
    (every topic's names and types); once a graph is up, a poll twice a second found nothing
    new, run after run.

    Args:
        base: s, the period after a poll that found something (> 0).
        maximum: s, the longest period (>= ``base``).
    """

    def __init__(self, base: float, maximum: float) -> None:
        if not (math.isfinite(base) and base > 0.0):
            raise CommonError(f'base must be finite and > 0, got {base}')
        if not (math.isfinite(maximum) and maximum >= base):
            raise CommonError(f'maximum must be finite and >= base ({base}), got {maximum}')
        self.base, self.maximum = float(base), float(maximum)
        self.period = self.base

    def after(self, found: bool) -> float:
        """The period after a poll that ``found`` something (or nothing)."""
        self.period = self.base if found else min(2.0 * self.period, self.maximum)
        return self.period


class ViewThrottle:
    """Messages only viewers read (markers), thinned: one per ``period`` of the caller's clock
    at most, but one whose content changed in kind (its ``key``: a plan's roles, the set of
    tracks) goes at once, so a viewer never waits for what matters. Building a MarkerArray in
    Python and recording it cost the graph more than a plan's markers are worth at 10 Hz
    (docs/performance.md).

    Args:
        period: s (>= 0); 0 lets every message through.
    """

    def __init__(self, period: float) -> None:
        if not (math.isfinite(period) and period >= 0.0):
            raise CommonError(f'period must be finite and >= 0, got {period}')
        self.period = float(period)
        self._last: float | None = None
        self._key: object = None

    def due(self, now: float, key: object = None) -> bool:
        """Whether the message of ``now`` (s) with content ``key`` goes out (and note it)."""
        if (
            self.period > 0.0
            and self._last is not None
            and key == self._key
            and self._last <= now < self._last + self.period - 1e-9
        ):
            return False
        self._last, self._key = now, key
        return True
