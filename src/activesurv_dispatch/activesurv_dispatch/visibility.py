"""Visibility measures (paper eq. 1-2, Appendix A).

``v_s = 1 / ||R||`` for one sensor and ``v_f = 1 / ||P||`` with ``P = (sum R_i^-1)^-1`` for a
fusion subset, where ``||.||`` is the Frobenius norm (the paper's "Euclidean norm" of a matrix)
and R is the 6x6 covariance of (x, y, z, n_x, n_y, n_z) from the sensor model. An occluded or
out-of-view sensor contributes nothing (R' = 0 in the paper: it is left out of the sum).

For the sensor model's covariances (diagonal in the camera frame, rotated block by block into
the world) the Frobenius norm is rotation invariant, so ``||R|| = sqrt(sum sigma_k^4)``; the
planner uses that to score thousands of candidate poses at once.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.errors import InformationError
from activesurv_common.information import covariance_visibility, information_fusion
from activesurv_dispatch.errors import VisibilityError

Array = NDArray[np.float64]


def _square(R: ArrayLike, name: str = 'R') -> Array:
    m = np.asarray(R, dtype=np.float64)
    if m.ndim != 2 or m.shape[0] != m.shape[1] or m.shape[0] == 0:
        raise VisibilityError(f'{name} must be a non-empty square matrix, got shape {m.shape}')
    if not np.all(np.isfinite(m)):
        raise VisibilityError(f'{name} has NaN or infinite entries')
    return m


def single_visibility(R: ArrayLike) -> float:
    """Eq. 1: ``1 / ||R||_F`` for an unoccluded sensor (``inf`` for a zero matrix).

    Raises:
        VisibilityError: (a ValueError) for a non-square or non-finite matrix.
    """
    return covariance_visibility(_square(R))


def fused_covariance(Rs: Sequence[ArrayLike]) -> Array:
    """``P = (sum R_i^-1)^-1`` (eq. 2; :func:`activesurv_common.information.information_fusion`).

    Raises:
        VisibilityError: for an empty list or malformed matrices.
    """
    mats = [_square(R, f'R[{i}]') for i, R in enumerate(Rs)]
    try:
        return information_fusion(mats)
    except InformationError as exc:
        raise VisibilityError(str(exc)) from exc


def fused_visibility(Rs: Sequence[ArrayLike]) -> float:
    """Eq. 2: ``1 / ||P||_F`` with ``P = (sum R_i^-1)^-1``; 0.0 for an empty list.

    Raises:
        VisibilityError: for malformed matrices.
    """
    if len(Rs) == 0:
        return 0.0
    return covariance_visibility(fused_covariance(Rs))


def visibility_from_variances(variances: ArrayLike) -> Array:
    """Batched eq. 1 for diagonal (in some frame) covariances: (N, 6) variances -> (N,)."""
    v = np.asarray(variances, dtype=np.float64)
    return np.asarray(1.0 / np.sqrt(np.sum(v * v, axis=-1)), dtype=np.float64)
