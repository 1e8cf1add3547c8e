"""Fault-tolerant Optimal Region fusion of one scalar variable (paper Section III-D-2, eq. 5-8).

Each concrete reading ``X`` with accuracy ``delta`` becomes an abstract sensor, the closed interval
``[X - delta, X + delta]``. With ``k`` intervals of which at most ``k_f`` may be faulty, the
*probable regions* are the maximal intervals on which the number of covering abstract sensors is
constant and at least ``k - k_f``; ``s_j`` is that number. The *optimal region* is the smallest
interval that contains every probable region, and the fused value is

    L = sum_j(q_j * s_j) / sum_j(s_j)                                           (eq. 8)

over the probable-region centres ``q_j``. A sensor that covers no probable region is faulty.
The default ``k_f`` is the largest one with ``k_f < k / 2`` (eq. 7): then the optimal region is
guaranteed to contain the true value (Marzullo 1990).

Cost: one sort of the 2k end points plus binary searches, O(k log k).
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass

from activesurv_fusion.errors import InvalidReadingError, NoConsensusError

__all__ = [
    'NoConsensusError',
    'OptimalRegion',
    'abstract_interval',
    'default_max_faulty',
    'optimal_region',
]


@dataclass(frozen=True)
class OptimalRegion:
    """Result of fusing one variable.

    Attributes:
        estimate: the fused value L (eq. 8).
        lower: lower bound of the optimal region.
        upper: upper bound of the optimal region.
        probable_regions: (lower, upper, count) of every probable region, in increasing order.
        faulty: indices (into the input) of the intervals that cover no probable region.
        max_faulty: the k_f used.
        threshold: k - k_f, the coverage a probable region needs.
    """

    estimate: float
    lower: float
    upper: float
    probable_regions: tuple[tuple[float, float, int], ...]
    faulty: tuple[int, ...]
    max_faulty: int
    threshold: int


def default_max_faulty(k: int) -> int:
    """The largest k_f with k_f < k / 2 (eq. 7)."""
    return max((k - 1) // 2, 0)


def abstract_interval(reading: float, sigma: float, z: float = 3.0) -> tuple[float, float]:
    """The abstract sensor of a reading: ``[X - z*sigma, X + z*sigma]`` (eq. 5).

    ``z = 3`` is the paper's 99.74 % confidence.

    Raises:
        InvalidReadingError: for a non-finite reading, or a sigma or z that is not finite and > 0.
    """
    if not math.isfinite(reading):
        raise InvalidReadingError(f'reading must be finite, got {reading}')
    if not (math.isfinite(sigma) and sigma > 0.0):
        raise InvalidReadingError(f'sigma must be finite and positive, got {sigma}')
    if not (math.isfinite(z) and z > 0.0):
        raise InvalidReadingError(f'z must be finite and positive, got {z}')
    delta = z * sigma
    return reading - delta, reading + delta


def _validated(intervals: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    if len(intervals) == 0:
        raise InvalidReadingError('optimal_region needs at least one interval, got none')
    out: list[tuple[float, float]] = []
    for i, pair in enumerate(intervals):
        try:
            lo, hi = (float(pair[0]), float(pair[1]))
            if len(pair) != 2:
                raise TypeError
        except (TypeError, ValueError, IndexError) as exc:
            raise InvalidReadingError(
                f'interval {i} must be a (lower, upper) pair of numbers, got {pair!r}'
            ) from exc
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise InvalidReadingError(f'interval {i} has a non-finite bound: ({lo}, {hi})')
        if lo > hi:
            raise InvalidReadingError(f'interval {i} has lower > upper: ({lo}, {hi})')
        out.append((lo, hi))
    return out


def optimal_region(
    intervals: Sequence[tuple[float, float]], max_faulty: int | None = None
) -> OptimalRegion:
    """Fuse abstract-sensor intervals with the Optimal Region algorithm.

    Args:
        intervals: one closed (lower, upper) interval per sensor.
        max_faulty: the number of faulty sensors tolerated, k_f; ``None`` for the largest
            k_f with k_f < k / 2.

    Returns:
        The optimal region, the fused estimate, the probable regions and the faulty sensors.

    Raises:
        ValueError: (an :class:`InvalidReadingError`) for empty input, a NaN or infinite bound,
            lower > upper, or a ``max_faulty`` outside ``0 .. k - 1``.
        NoConsensusError: when no point is covered by at least ``k - k_f`` intervals.
    """
    ivs = _validated(intervals)
    k = len(ivs)
    k_f = default_max_faulty(k) if max_faulty is None else int(max_faulty)
    if not 0 <= k_f < k:
        raise InvalidReadingError(f'max_faulty must be in 0..{k - 1} for {k} intervals, got {k_f}')
    return optimal_region_unchecked(ivs, k_f)


def optimal_region_unchecked(ivs: Sequence[tuple[float, float]], k_f: int) -> OptimalRegion:
    """:func:`optimal_region` for intervals and k_f already validated (the pose-fusion path)."""
    k = len(ivs)
    need = k - k_f

    lows = sorted(lo for lo, _ in ivs)
    highs = sorted(hi for _, hi in ivs)

    # Sweep the distinct end points in order. At a point x the closed intervals that cover it
    # are those started at or before x and not ended before x; in the open gap after x, those
    # ended at x no longer count. Pieces (point, gap, point, ...) with equal counts merge into
    # maximal regions; regions with count >= need are the probable regions.
    regions: list[tuple[float, float, int]] = []
    cur_lo = cur_hi = 0.0
    cur_count = -1
    count = i = j = 0
    while j < k:  # highs end last: every interval's upper bound is >= its lower bound
        x = lows[i] if i < k and lows[i] <= highs[j] else highs[j]
        while i < k and lows[i] == x:
            count += 1
            i += 1
        if count == cur_count:
            cur_hi = x
        else:
            if cur_count >= need:
                regions.append((cur_lo, cur_hi, cur_count))
            cur_lo = cur_hi = x
            cur_count = count
        while j < k and highs[j] == x:
            count -= 1
            j += 1
        if j < k:
            nxt = lows[i] if i < k and lows[i] < highs[j] else highs[j]
            if count == cur_count:
                cur_hi = nxt
            else:
                if cur_count >= need:
                    regions.append((cur_lo, cur_hi, cur_count))
                cur_lo, cur_hi, cur_count = x, nxt, count
    if cur_count >= need:
        regions.append((cur_lo, cur_hi, cur_count))

    if not regions:
        raise NoConsensusError(
            f'no point is covered by {need} of the {k} intervals (k_f = {k_f}): '
            'the readings disagree by more than their stated accuracy'
        )

    total = sum(s for _, _, s in regions)
    estimate = sum(0.5 * (lo + hi) * s for lo, hi, s in regions) / total
    starts = [lo for lo, _, _ in regions]
    faulty: list[int] = []
    for i, (lo, hi) in enumerate(ivs):
        # Probable regions are disjoint and sorted: the first one starting at or after `lo`
        # is the only candidate that could end at or before `hi`.
        j = bisect_left(starts, lo)
        if not (j < len(regions) and regions[j][1] <= hi):
            faulty.append(i)

    return OptimalRegion(
        estimate=float(estimate),
        lower=regions[0][0],
        upper=regions[-1][1],
        probable_regions=tuple(regions),
        faulty=tuple(faulty),
        max_faulty=k_f,
        threshold=need,
    )
