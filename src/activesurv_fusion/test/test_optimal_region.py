"""Core tests of Optimal Region (no ROS)."""

from __future__ import annotations

import math
from itertools import pairwise, permutations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_fusion.optimal_region import (
    NoConsensusError,
    OptimalRegion,
    abstract_interval,
    default_max_faulty,
    optimal_region,
)

# The paper's Fig. 7: sensor 1 reads 601 +- 5 mm; sensors 1, 3 and 4 agree on 600-603 mm,
# sensor 2 agrees with nobody.
PAPER = [(596.0, 606.0), (585.0, 594.0), (600.0, 610.0), (592.0, 603.0)]


def test_paper_worked_example() -> None:
    r = optimal_region(PAPER)
    assert isinstance(r, OptimalRegion)
    assert r.max_faulty == 1
    assert r.threshold == 3
    assert (r.lower, r.upper) == (600.0, 603.0)
    assert r.estimate == pytest.approx(601.5)
    assert r.faulty == (1,)
    assert r.probable_regions == ((600.0, 603.0, 3),)


@pytest.mark.parametrize(('k', 'expected'), [(1, 0), (2, 0), (3, 1), (4, 1), (5, 2), (6, 2)])
def test_default_max_faulty_is_largest_below_half(k: int, expected: int) -> None:
    assert default_max_faulty(k) == expected
    assert expected < k / 2


def test_single_interval_is_its_own_region() -> None:
    r = optimal_region([(1.0, 3.0)])
    assert (r.lower, r.upper, r.estimate, r.faulty) == (1.0, 3.0, 2.0, ())


def test_no_fault_regions_with_different_counts_are_weighted() -> None:
    # k = 4, k_f = 1: [2, 3] is covered by 4 sensors, [1, 2) and (3, 4] by 3.
    r = optimal_region([(0.0, 4.0), (1.0, 5.0), (2.0, 3.0), (-1.0, 4.0)])
    counts = [c for _, _, c in r.probable_regions]
    assert 4 in counts
    assert r.lower == pytest.approx(1.0)
    assert r.upper == pytest.approx(4.0)
    num = sum(0.5 * (lo + hi) * c for lo, hi, c in r.probable_regions)
    assert r.estimate == pytest.approx(num / sum(counts))
    assert r.faulty == ()


def test_two_disjoint_readings_have_no_consensus() -> None:
    with pytest.raises(NoConsensusError, match='2 of the 2'):
        optimal_region([(0.0, 1.0), (2.0, 3.0)])


def test_no_consensus_when_three_readings_all_disagree() -> None:
    with pytest.raises(NoConsensusError):
        optimal_region([(0.0, 1.0), (2.0, 3.0), (4.0, 5.0)])


def test_touching_intervals_meet_in_a_point() -> None:
    r = optimal_region([(0.0, 1.0), (1.0, 2.0)])
    assert (r.lower, r.upper, r.estimate) == (1.0, 1.0, 1.0)


def test_explicit_max_faulty_zero_demands_full_agreement() -> None:
    with pytest.raises(NoConsensusError):
        optimal_region(PAPER, max_faulty=0)


@pytest.mark.parametrize(
    'bad',
    [
        [],
        [(float('nan'), 1.0)],
        [(0.0, float('inf'))],
        [(2.0, 1.0)],
        [(1.0,)],
        [('a', 'b')],
    ],
)
def test_invalid_intervals_raise_value_error(bad: list) -> None:  # type: ignore[type-arg]
    with pytest.raises(ValueError):  # noqa: PT011 - any clear ValueError is the contract
        optimal_region(bad)


@pytest.mark.parametrize('max_faulty', [-1, 4, 7])
def test_max_faulty_out_of_range_raises(max_faulty: int) -> None:
    with pytest.raises(ValueError, match='max_faulty'):
        optimal_region(PAPER, max_faulty=max_faulty)


def test_abstract_interval() -> None:
    assert abstract_interval(601.0, 5.0 / 3.0) == pytest.approx((596.0, 606.0))
    with pytest.raises(ValueError, match='sigma'):
        abstract_interval(1.0, 0.0)
    with pytest.raises(ValueError, match='reading'):
        abstract_interval(float('nan'), 1.0)


def _brute_force(ivs: list[tuple[float, float]], k_f: int) -> tuple[float, float, set[int]]:
    """Reference: sample every end point and every gap midpoint, find covered points."""
    need = len(ivs) - k_f
    pts = sorted({p for iv in ivs for p in iv})
    samples = pts + [0.5 * (a + b) for a, b in pairwise(pts)]
    good = [x for x in samples if sum(lo <= x <= hi for lo, hi in ivs) >= need]
    if not good:
        raise NoConsensusError('none')
    lo, hi = min(good), max(good)
    covering = {i for i, (a, b) in enumerate(ivs) if any(a <= x <= b for x in good)}
    return lo, hi, covering


interval = st.tuples(st.floats(-100, 100, allow_nan=False), st.floats(0, 30, allow_nan=False)).map(
    lambda t: (t[0], t[0] + t[1])
)


@settings(max_examples=300, deadline=None)
@given(st.lists(interval, min_size=1, max_size=9))
def test_properties_against_brute_force(ivs: list[tuple[float, float]]) -> None:
    k_f = default_max_faulty(len(ivs))
    try:
        ref = _brute_force(ivs, k_f)
    except NoConsensusError:
        with pytest.raises(NoConsensusError):
            optimal_region(ivs)
        return
    r = optimal_region(ivs)
    assert r.lower == pytest.approx(ref[0])
    assert r.upper == pytest.approx(ref[1])
    # The estimate always lies inside the optimal region.
    assert r.lower - 1e-9 <= r.estimate <= r.upper + 1e-9
    # Every probable region is covered by at least k - k_f intervals, and lies in the region.
    for lo, hi, count in r.probable_regions:
        assert count >= len(ivs) - k_f
        assert r.lower <= lo <= hi <= r.upper
    # A sensor that covers some point of a probable region is not faulty (regions are maximal,
    # so covering a point of one means covering all of it).
    assert set(r.faulty) == set(range(len(ivs))) - ref[2]


@settings(max_examples=200, deadline=None)
@given(st.lists(interval, min_size=1, max_size=7), st.randoms(use_true_random=False))
def test_permuting_inputs_changes_nothing(ivs: list[tuple[float, float]], rnd: object) -> None:
    order = list(range(len(ivs)))
    rnd.shuffle(order)  # type: ignore[attr-defined]
    try:
        a = optimal_region(ivs)
    except NoConsensusError:
        with pytest.raises(NoConsensusError):
            optimal_region([ivs[i] for i in order])
        return
    b = optimal_region([ivs[i] for i in order])
    assert (a.lower, a.upper) == (b.lower, b.upper)
    assert a.estimate == pytest.approx(b.estimate)
    assert sorted(a.faulty) == sorted(order[j] for j in b.faulty)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-50, 50, allow_nan=False),
    st.lists(st.tuples(st.floats(0.01, 5), st.floats(0.01, 5)), min_size=1, max_size=8),
)
def test_without_faults_the_estimate_lies_in_the_intersection(
    truth: float, widths: list[tuple[float, float]]
) -> None:
    # All intervals contain the truth: they overlap, and with k_f = 0 the region is their
    # intersection, which contains the estimate.
    ivs = [(truth - a, truth + b) for a, b in widths]
    r = optimal_region(ivs, max_faulty=0)
    lo = max(a for a, _ in ivs)
    hi = min(b for _, b in ivs)
    assert lo - 1e-9 <= r.estimate <= hi + 1e-9
    assert r.faulty == ()
    # The default k_f also keeps the truth inside the optimal region.
    d = optimal_region(ivs)
    assert d.lower - 1e-9 <= truth <= d.upper + 1e-9


def test_many_permutations_of_the_paper_example() -> None:
    for order in permutations(range(4)):
        r = optimal_region([PAPER[i] for i in order])
        assert r.estimate == pytest.approx(601.5)
        assert [order[j] for j in r.faulty] == [1]
        assert math.isclose(r.lower, 600.0)
        assert math.isclose(r.upper, 603.0)
