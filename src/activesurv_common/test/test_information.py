"""Eq. 2 written once: information fusion of covariances, and its visibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.errors import InformationError
from activesurv_common.information import (
    covariance_visibility,
    fused_visibility,
    information_fusion,
)


def test_hand_computed_pair() -> None:
    A = np.array([[2.0, 0.5], [0.5, 1.0]])
    B = np.diag([1.0, 3.0])
    # A^-1 = [[4, -2], [-2, 8]] / 7, B^-1 = diag(1, 1/3): the sum is
    # [[11/7, -2/7], [-2/7, 31/21]] with determinant 47/21, so P = [[31, 6], [6, 33]] / 47.
    P = information_fusion([A, B])
    assert pytest.approx(np.array([[31.0, 6.0], [6.0, 33.0]]) / 47.0) == P
    assert covariance_visibility(P) == pytest.approx(47.0 / math.sqrt(2122.0))
    assert fused_visibility([A, B]) == pytest.approx(47.0 / math.sqrt(2122.0))


def test_identical_sensors_divide_the_covariance() -> None:
    R = np.diag([4.0, 9.0])
    assert information_fusion([R, R, R, R]) == pytest.approx(R / 4.0)
    assert fused_visibility([R] * 4) == pytest.approx(4.0 / math.sqrt(16.0 + 81.0))


def test_singular_covariance_falls_back_to_the_pseudo_inverse() -> None:
    # A sensor that measures nothing of the second component (pinv gives it zero information).
    P = information_fusion([np.diag([1.0, 0.0]), np.diag([1.0, 0.0])])
    assert pytest.approx(np.diag([0.5, 0.0])) == P


def test_edge_cases() -> None:
    assert fused_visibility([]) == 0.0
    assert covariance_visibility(np.zeros((3, 3))) == math.inf
    with pytest.raises(InformationError, match='at least one'):
        information_fusion([])
    with pytest.raises(InformationError, match='NaN'):
        information_fusion([np.full((2, 2), np.nan)])
    with pytest.raises(InformationError, match='same shape'):
        information_fusion([np.eye(2), np.eye(3)])
    with pytest.raises(InformationError, match='square'):
        covariance_visibility(np.zeros((2, 3)))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 5))
def test_fused_covariance_is_spd_and_below_each_input(seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    covs = []
    for _ in range(k):
        M = rng.normal(size=(6, 6))
        covs.append(M @ M.T + 0.1 * np.eye(6))
    P = information_fusion(covs)
    assert np.allclose(P, P.T)
    assert np.all(np.linalg.eigvalsh(P) > 0.0)
    for R in covs:  # fusing never loses information: R - P is positive semi-definite
        assert np.min(np.linalg.eigvalsh(R - P)) > -1e-9 * np.max(np.abs(R))
