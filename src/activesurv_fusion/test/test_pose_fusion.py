"""Core tests of pose fusion and the demand collector (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.statuses import DemandStatus
from activesurv_fusion.collector import (
    Answer,
    DemandCollector,
    Outcome,
    resolve,
)
from activesurv_fusion.errors import InvalidReadingError, NoConsensusError
from activesurv_fusion.pose_fusion import (
    PoseReading,
    fuse_poses,
    information_fusion,
    median_fusion,
    weighted_mean_fusion,
)

SIGMA_P, SIGMA_N = 0.3e-3, 4e-3
COV = np.diag([SIGMA_P**2] * 3 + [SIGMA_N**2] * 3)
TRUTH_P = np.array([0.2, 0.1, 0.04])
TRUTH_N = np.array([0.0, -1.0, 0.0])


def _readings(seed: int, bias: dict[str, float] | None = None) -> list[PoseReading]:
    rng = np.random.default_rng(seed)
    out = []
    for cam in ('cam1', 'cam2', 'cam3', 'cam4'):
        p = TRUTH_P + rng.normal(0, SIGMA_P, 3)
        p[0] += (bias or {}).get(cam, 0.0)
        n = TRUTH_N + rng.normal(0, SIGMA_N, 3)
        out.append(PoseReading.create(cam, p, n, COV))
    return out


@pytest.mark.parametrize('seed', range(10))
def test_biased_camera_is_discarded(seed: int) -> None:
    readings = _readings(seed, {'cam2': 5 * 3 * SIGMA_P})
    fused = fuse_poses(readings)
    assert fused.cameras_faulty == ('cam2',)
    assert fused.cameras_used == ('cam1', 'cam3', 'cam4')
    assert np.linalg.norm(fused.position - TRUTH_P) < 4 * SIGMA_P
    # The non-tolerant weighted mean is pulled by a quarter of the bias.
    wm = weighted_mean_fusion(readings)
    assert abs(wm[0] - TRUTH_P[0]) > abs(fused.position[0] - TRUTH_P[0])


def test_fused_covariance_is_information_sum_of_used() -> None:
    fused = fuse_poses(_readings(3, {'cam4': 0.01}))
    assert np.allclose(fused.covariance, COV / 3)
    assert np.allclose(information_fusion([COV, COV]), COV / 2)


def test_normal_is_renormalised_and_bounds_bracket_estimate() -> None:
    fused = fuse_poses(_readings(4))
    assert np.linalg.norm(fused.normal) == pytest.approx(1.0)
    est = np.concatenate([fused.position, fused.normal])
    raw = np.array([r.estimate for r in fused.regions])
    assert np.all(fused.lower <= raw + 1e-12)
    assert np.all(raw <= fused.upper + 1e-12)
    assert np.degrees(np.arccos(est[3:] @ TRUTH_N)) < 1.0


def test_two_disagreeing_cameras_give_no_consensus() -> None:
    a = PoseReading.create('cam1', TRUTH_P, TRUTH_N, COV)
    b = PoseReading.create('cam2', TRUTH_P + np.array([0.01, 0, 0]), TRUTH_N, COV)
    with pytest.raises(NoConsensusError, match='variable x'):
        fuse_poses([a, b])


@pytest.mark.parametrize(
    ('position', 'normal', 'cov'),
    [
        ([np.nan, 0, 0], [0, 0, 1], COV),
        ([0, 0, 0], [0, 0, 0], COV),
        ([0, 0, 0], [0, 0, 1], np.zeros((6, 6))),
        ([0, 0, 0], [0, 0, 1], np.eye(5)),
    ],
)
def test_bad_readings_are_rejected(position: list, normal: list, cov: np.ndarray) -> None:  # type: ignore[type-arg]
    with pytest.raises(InvalidReadingError):
        PoseReading.create('camX', position, normal, cov)


def test_duplicate_cameras_rejected() -> None:
    r = PoseReading.create('cam1', TRUTH_P, TRUTH_N, COV)
    with pytest.raises(InvalidReadingError, match='duplicate'):
        fuse_poses([r, r])


def test_median_baseline() -> None:
    out = median_fusion(_readings(5))
    assert np.linalg.norm(out[:3] - TRUTH_P) < 3 * SIGMA_P


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 10_000), st.permutations(range(4)))
def test_pose_fusion_is_permutation_invariant(seed: int, order: list[int]) -> None:
    readings = _readings(seed, {'cam3': 0.002})
    try:
        a = fuse_poses(readings)
    except NoConsensusError:
        return
    b = fuse_poses([readings[i] for i in order])
    assert np.allclose(a.position, b.position)
    assert a.cameras_faulty == b.cameras_faulty
    # SPD fused covariance.
    assert np.all(np.linalg.eigvalsh(a.covariance) > 0)


# -- collector -------------------------------------------------------------------------------


def _ok(cam: str, reading: PoseReading) -> Answer:
    return Answer(cam, Outcome.OK, reading)


def test_collector_completes_when_all_assigned_answer() -> None:
    c = DemandCollector(timeout=2.0)
    readings = _readings(1)
    c.request(7, demand_time=10.0, cameras=('cam1', 'cam2', 'cam3'), now=9.0)
    for r in readings[:2]:
        c.observe(7, _ok(r.camera_id, r), now=10.1, demand_time=10.0)
    assert c.pop_ready(10.2) == []
    c.observe(7, _ok('cam3', readings[2]), now=10.3, demand_time=10.0)
    (batch,) = c.pop_ready(10.3)
    result = resolve(batch)
    assert result.status is DemandStatus.OK
    assert result.fused is not None
    assert result.fused_visibility > 0


def test_collector_times_out_with_partial_answer() -> None:
    c = DemandCollector(timeout=2.0)
    readings = _readings(2)
    c.request(1, 10.0, ('cam1', 'cam2', 'cam3'), now=9.0)
    c.observe(1, _ok('cam1', readings[0]), 10.1, 10.0)
    c.observe(1, Answer('cam2', Outcome.FAILED, None, 'marker not found'), 10.1, 10.0)
    assert c.pop_ready(11.9) == []
    (batch,) = c.pop_ready(12.0)
    result = resolve(batch)
    assert result.status is DemandStatus.PARTIAL
    assert result.cameras_missing == ('cam3',)
    assert result.cameras_failed == ('cam2',)
    assert 'marker not found' in result.reason


def test_collector_answers_a_demand_nobody_observed() -> None:
    c = DemandCollector(timeout=1.0)
    c.request(3, 5.0, ('cam1',), now=5.0)
    (batch,) = c.pop_ready(6.0)
    result = resolve(batch)
    assert result.status is DemandStatus.NO_OBSERVATIONS
    assert result.fused is None
    assert result.fused_visibility == 0.0


def test_orphan_observation_opens_a_demand_and_late_ones_are_counted() -> None:
    c = DemandCollector(timeout=1.0)
    r = _readings(3)[0]
    c.observe(4, _ok('cam1', r), now=20.0, demand_time=20.0)
    (batch,) = c.pop_ready(21.0)
    assert resolve(batch).status is DemandStatus.OK
    assert not c.observe(4, _ok('cam2', r), now=21.5, demand_time=20.0)
    assert c.late_observations == 1
    assert c.is_closed(4)
    assert not c.request(4, 20.0, ('cam1',), now=22.0)


def test_flush_answers_everything_open() -> None:
    c = DemandCollector(timeout=100.0)
    c.request(1, 0.0, ('cam1',), now=0.0)
    c.request(2, 1.0, ('cam1',), now=0.0)
    assert [b.index for b in c.flush()] == [1, 2]
    assert c.open_indices == ()


def test_collector_rejects_bad_timeout() -> None:
    with pytest.raises(ValueError, match='timeout'):
        DemandCollector(timeout=float('nan'))


def test_a_demand_without_cameras_gets_an_explicit_failure() -> None:
    c = DemandCollector(timeout=0.5)
    c.request(9, 3.0, (), now=3.0)
    assert c.pop_ready(3.2) == []
    (batch,) = c.pop_ready(3.5)
    result = resolve(batch)
    assert result.status is DemandStatus.NO_OBSERVATIONS
    assert 'no camera was assigned' in result.reason
