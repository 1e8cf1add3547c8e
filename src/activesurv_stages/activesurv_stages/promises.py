"""The stage state at a demand instant, known before the instant (pure core of the bridge).

A capture request names the demand instant ``t`` and its cameras; from then on the dispatcher
holds those cameras still until ``t``. A bridge whose axes stand still (every axis idle, no goal
queued) therefore knows where they will be at ``t``: where they are. It publishes that state
stamped ``t`` at once (or as soon as the axes come to rest before ``t``), so that the imager has
the state at hand when the frame of ``t`` arrives instead of waiting for the next poll after
it. The first report after ``t`` checks the promise: an axis that moved anyway (a goal from
elsewhere, a stall) is counted and said, and its report published as usual.

With ``hold`` > 0 (free-running cameras: the dispatcher holds the cameras still until ``t +
hold``, as far as the frame nearest the instant may lie after it) the same positions are
promised for ``t + hold`` as well: the imager interpolates between the two for any frame in
between, and the first report after ``t + hold`` checks that one too.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

TOLERANCE = 1e-4  # m or rad: a promise kept to within this


@dataclass
class Promises:
    """Open demand instants of one bridge and the states promised for them."""

    tolerance: float = TOLERANCE
    hold: float = 0.0  # s past each instant the axes are promised still as well
    pending: set[float] = field(default_factory=set)  # instants still to promise
    made: dict[float, dict[str, float]] = field(default_factory=dict)  # instant: positions
    kept: int = 0
    broken: int = 0

    def request(self, t: float, now: float) -> None:
        """A capture request of this bridge's camera for instant ``t`` (ignored if past)."""
        if t > now and t not in self.made:
            self.pending.add(t)

    def due(
        self, now: float, standing_still: bool, positions: Mapping[str, float]
    ) -> list[tuple[float, dict[str, float]]]:
        """The promises to publish now: (instant, positions) for every pending instant still
        ahead while the axes stand still."""
        self.pending = {t for t in self.pending if t > now}
        if not standing_still or not positions or not self.pending:
            return []
        ends = [t + self.hold for t in self.pending] if self.hold > 0.0 else []
        out = [(t, dict(positions)) for t in sorted([*self.pending, *ends])]
        self.made.update(out)
        self.pending.clear()
        return out

    def check(self, report_time: float, positions: Mapping[str, float]) -> list[str]:
        """The first report after promised instants: why each broken promise was broken."""
        out = []
        for t in sorted(k for k in self.made if k <= report_time):
            promised = self.made.pop(t)
            moved = {
                j: positions[j] - p
                for j, p in promised.items()
                if j in positions and abs(positions[j] - p) > self.tolerance
            }
            if moved:
                self.broken += 1
                what = ', '.join(f'{j} by {d:+.4g}' for j, d in sorted(moved.items()))
                out.append(f'the state promised for the instant {t:.3f} s was not kept: {what}')
            else:
                self.kept += 1
        return out
