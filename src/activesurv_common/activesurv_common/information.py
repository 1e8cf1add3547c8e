"""Information fusion of covariances, the paper's eq. 2, written once.

``P = (sum_i R_i^-1)^-1`` is the covariance of the fused estimate of k independent sensors, and
``v = 1 / ||P||_F`` its visibility (eq. 1 for k = 1, eq. 2 otherwise; ``||.||_F`` is the
Frobenius norm, the paper's "Euclidean norm" of a matrix). The dispatcher scores candidate
subsets with it before a capture; fusion reports it for the cameras it used after one: the same
function, so the two always agree.

A singular covariance (a sensor that measures some component perfectly, or not at all) falls
back to the Moore-Penrose pseudo-inverse; the result is symmetrised against round-off.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.errors import InformationError

Array = NDArray[np.float64]


def _inverse(m: Array) -> Array:
    """Inverse of a stack of square matrices; pseudo-inverse where one is singular."""
    try:
        return np.asarray(np.linalg.inv(m), dtype=np.float64)
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.pinv(m), dtype=np.float64)


def check_covariances(covariances: Sequence[ArrayLike] | ArrayLike) -> Array:
    """The covariances as one finite (k, n, n) array.

    Raises:
        InformationError: if there are none, or they are not finite square matrices of one size.
    """
    try:
        stack = np.asarray(covariances, dtype=np.float64)
    except ValueError as exc:  # ragged: matrices of different sizes
        raise InformationError(f'covariances must all have the same shape: {exc}') from exc
    if stack.ndim == 2:
        stack = stack[np.newaxis]
    if stack.ndim != 3 or stack.shape[0] == 0:
        raise InformationError('information fusion needs at least one covariance matrix')
    if stack.shape[1] != stack.shape[2] or stack.shape[1] == 0:
        raise InformationError(f'covariances must be non-empty square matrices, got {stack.shape}')
    if not np.all(np.isfinite(stack)):
        raise InformationError('a covariance has NaN or infinite entries')
    return stack


def information_fusion(covariances: Sequence[ArrayLike] | ArrayLike) -> Array:
    """``P = (sum R_i^-1)^-1`` (eq. 2).

    Args:
        covariances: k covariance matrices (n x n), or a (k, n, n) array.

    Returns:
        The fused (n, n) covariance, symmetric.

    Raises:
        InformationError: (a ValueError) for an empty list or malformed matrices.
    """
    stack = check_covariances(covariances)
    P = _inverse(_inverse(stack).sum(axis=0))
    return np.asarray(0.5 * (P + P.T), dtype=np.float64)


def covariance_visibility(P: ArrayLike) -> float:
    """``1 / ||P||_F``; ``inf`` for a zero matrix (a perfect sensor).

    Raises:
        InformationError: for a non-finite or non-square matrix.
    """
    m = check_covariances(P)[0]
    norm = float(np.linalg.norm(m, 'fro'))
    return math.inf if norm == 0.0 else 1.0 / norm


def fused_visibility(covariances: Sequence[ArrayLike]) -> float:
    """Eq. 2: ``1 / ||(sum R_i^-1)^-1||_F``; 0.0 when no sensor contributes (the paper's R' = 0).

    Raises:
        InformationError: for malformed matrices.
    """
    if len(covariances) == 0:
        return 0.0
    return covariance_visibility(information_fusion(covariances))
