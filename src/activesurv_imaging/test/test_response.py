"""The camera's response (gamma) from the calibration boards' blurred edges (issue 33, item 1:
"commissioning estimates it from the boards' grey levels")."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from activesurv_imaging.calibration import find_corners
from activesurv_imaging.response import BoardReader, edge_samples, estimate_gamma

SQUARES = (10, 7)


def board(gamma: float, sigma: float, seed: int = 0, angle: float = 0.2) -> np.ndarray:
    """A 10 x 7 board of 30 px squares (black 0.05, white 0.9 of full scale), blurred in
    radiance by ``sigma`` px, seen through ``gamma``, with a grey level of noise."""
    h, w, ss = 480, 640, 4
    yy, xx = np.mgrid[0 : h * ss, 0 : w * ss] / ss
    c, s = np.cos(angle), np.sin(angle)
    u = (xx - 100) * c + (yy - 80) * s
    v = -(xx - 100) * s + (yy - 80) * c
    on = (u >= 0) & (u < 300) & (v >= 0) & (v < 210)
    white = (np.floor(u / 30) + np.floor(v / 30)) % 2 == 1
    lin = np.where(on, np.where(white, 0.9, 0.05), 0.5).reshape(h, ss, w, ss).mean(axis=(1, 3))
    lin = cv2.GaussianBlur(lin, (0, 0), sigma)
    grey = 255.0 * lin ** (1.0 / gamma) + np.random.default_rng(seed).normal(0.0, 1.0, lin.shape)
    return np.clip(grey, 0, 255).astype(np.uint8)


@pytest.mark.parametrize('gamma', [1.0, 1.8, 2.2])
def test_gamma_is_found_from_blurred_board_edges(gamma: float) -> None:
    views = []
    for seed, angle in ((0, 0.2), (1, 0.5)):
        img = board(gamma, 2.5, seed, angle)
        corners = find_corners(img, SQUARES)
        assert corners is not None
        views.append(edge_samples(img, corners, SQUARES))
    est = estimate_gamma(views)
    assert est is not None
    assert est.gamma == pytest.approx(gamma, rel=0.1)
    assert est.profiles > 100


def test_sharp_edges_say_nothing_and_the_reader_keeps_the_views() -> None:
    reader = BoardReader(SQUARES)
    assert reader(board(2.2, 0.7)) is not None
    assert len(reader.edges) == 1
    assert reader.gamma() is None  # a pixel-wide ramp hides the response: none guessed
    assert reader(np.zeros((480, 640), np.uint8)) is None  # no board: no view kept
    assert len(reader.edges) == 1
    reader(board(2.2, 2.5))
    est = reader.gamma()
    assert est is not None
    assert est.gamma == pytest.approx(2.2, rel=0.1)


def test_bad_corner_lists_are_refused() -> None:
    img = board(1.0, 2.0)
    with pytest.raises(ValueError, match='corners'):
        edge_samples(img, np.zeros((5, 2)), SQUARES)
    with pytest.raises(ValueError, match='8-bit'):
        edge_samples(img.astype(np.float32), np.zeros((54, 2)), SQUARES)


def test_corners_are_refined_again_in_linear_radiance_in_their_order() -> None:
    reader = BoardReader(SQUARES)
    img = board(2.2, 2.5)
    corners = reader(img)
    assert corners is not None
    again = reader.linearised(corners, 2.2)
    assert again.shape == corners.shape
    assert np.abs(again - corners).max() < 0.5  # the same corners, refined again
    backwards = reader.linearised(corners[::-1], 2.2)
    assert np.allclose(backwards, again[::-1], atol=1e-6)  # the caller's order is kept
    assert np.allclose(reader.linearised(corners, 1.0), corners, atol=1e-6)
    elsewhere = corners + 5.0  # not a kept view's corners: left as they are
    assert np.array_equal(reader.linearised(elsewhere, 2.2), elsewhere)
