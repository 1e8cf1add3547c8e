"""Which of the table's object states a triggered camera needs: those around its instants.

A simulated camera that images only on capture requests reads the object's truth at a
requested instant ``t`` and nowhere else: the state stamped ``t`` (its frame's check and its
fallback render), the states on either side (the streak's rates over the exposure, an
extrapolation when the instant's state is late). On ``object_state`` it heard every state of
the table (about 13 a second) and woke for each: with four such cameras, 3 % of a Set A run's
CPU in alternating runs (docs/performance.md). The xy table therefore also sends, on
``sim/instant_object_state``, only the states stamped within ``[t - before, t + after]`` of a
requested instant, as they are published; a request that comes when some of them have gone
out already gets those again (the table keeps the last ``keep`` seconds of its states).
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Sequence
from typing import Generic, TypeVar

T = TypeVar('T')

EPS = 1e-9


class InstantWindows(Generic[T]):
    """The states (any payload, ``T``) around requested instants.

    Args:
        before: s before an instant whose states are sent.
        after: s after it.
        keep: s of published states kept for a request that comes late.
    """

    def __init__(self, before: float, after: float, keep: float = 5.0) -> None:
        for name, v in (('before', before), ('after', after), ('keep', keep)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f'{name} must be finite and >= 0, got {v!r}')
        self.before, self.after, self.keep = before, after, keep
        self._instants: list[float] = []  # sorted, the requested ones of the last ``keep`` s
        self._history: deque[tuple[float, Sequence[T]]] = deque()
        self._sent: set[float] = set()  # stamps sent already (windows may overlap)

    def wanted(self, stamp: float) -> bool:
        """Whether a state stamped ``stamp`` lies in a requested instant's window."""
        i = bisect.bisect_left(self._instants, stamp - self.after - EPS)
        return i < len(self._instants) and self._instants[i] <= stamp + self.before + EPS

    def published(self, stamp: float, states: Sequence[T]) -> Sequence[T]:
        """The table published ``states`` stamped ``stamp``: what of them to send (all or none)."""
        if not math.isfinite(stamp):
            return ()
        self._history.append((stamp, states))
        self._forget(stamp)
        if stamp in self._sent or not self.wanted(stamp):
            return ()
        self._sent.add(stamp)
        return states

    def requested(self, instant: float) -> list[T]:
        """A capture request for ``instant``: the states of its window published already and
        not sent yet, oldest first (the rest go as they are published)."""
        if not math.isfinite(instant):
            return []
        if instant not in self._instants:
            bisect.insort(self._instants, instant)
        out: list[T] = []
        for stamp, states in self._history:
            if stamp in self._sent:
                continue
            if instant - self.before - EPS <= stamp <= instant + self.after + EPS:
                self._sent.add(stamp)
                out.extend(states)
        return out

    def _forget(self, now: float) -> None:
        old = now - self.keep
        while self._history and self._history[0][0] < old:
            self._sent.discard(self._history.popleft()[0])
        while self._instants and self._instants[0] < old - self.after:
            self._instants.pop(0)
