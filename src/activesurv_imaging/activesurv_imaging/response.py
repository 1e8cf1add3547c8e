"""The camera's response (gamma), estimated from the edges of the calibration boards.

A board's edge between a black and a white square, blurred by the lens (and the pixel), is a
step convolved with a symmetric blur: *in radiance* its profile across the edge is point-symmetric
about the half-way point, ``p(x0 + u) + p(x0 - u) = 1``. A camera's response ``grey = 255
(radiance / full scale)^(1 / gamma)`` bends it: with gamma > 1 the bright half is stretched, and
the 75 % crossing lies farther from the 50 % one than the 25 % crossing does. Undoing the response
with the right gamma makes every profile symmetric again; :func:`estimate_gamma` finds that gamma
(the root of the profiles' median asymmetry) from the profiles :func:`edge_profiles` samples at
the middle of every edge between two neighbouring inner corners. No target with grey patches is
needed: the commissioning boards carry it. Sharp edges (a ramp of a pixel or two) still do, but
with more noise per profile; a hundred profiles give gamma within a few per cent.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from activesurv_imaging.calibration import find_corners, refine_corners
from activesurv_imaging.detect import first_crossing

Array = NDArray[np.float64]

GAMMA_RANGE = (0.3, 4.0)
MIN_PROFILES = 40  # fewer: no estimate (the calibration keeps its gamma)
MAX_EDGES = 3000  # more: a subset of the views is enough
MIN_CONTRAST = 60.0  # grey levels between a profile's plateaus


@dataclass(frozen=True)
class GammaEstimate:
    """A camera's response from its board edges.

    Attributes:
        gamma: the estimate (1: linear).
        profiles: how many edge profiles it rests on.
        spread: the estimate's standard error (from the profiles' scatter, by the bootstrap's
            simplest form: the asymmetry's slope and its scatter).
    """

    gamma: float
    profiles: int
    spread: float


@dataclass(frozen=True, eq=False)
class EdgeSamples:
    """Pixels near the board's edges: for each edge (between two neighbouring inner corners)
    its pixels' grey levels and their signed distances across it (px, dark side negative).

    Attributes:
        across: (E, S) distances (float32).
        grey: (E, S) grey levels (uint8).
        half: px either side of the edge the samples reach.
    """

    across: NDArray[np.float32]
    grey: NDArray[np.uint8]
    half: float
    # The binning across the edge, the same for every gamma (computed once).
    _flat: NDArray[np.int64] = field(init=False, repr=False, compare=False)
    _count: NDArray[np.int64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        nbins = max(math.floor(2.0 * self.half / BIN), 2)
        idx = np.clip(((self.across + self.half) / BIN).astype(np.int64), 0, nbins - 1)
        flat = (idx + np.arange(len(self.across))[:, None] * nbins).ravel()
        count = np.bincount(flat, minlength=len(self.across) * nbins).reshape(-1, nbins)
        object.__setattr__(self, '_flat', flat)
        object.__setattr__(self, '_count', count)

    def __len__(self) -> int:
        return len(self.across)


def edge_samples(image: ArrayLike, corners: ArrayLike, squares: tuple[int, int]) -> EdgeSamples:
    """The pixels across every edge between two neighbouring inner corners, over the middle
    half of the edge and 0.35 of the corners' spacing either side, each with its distance
    across the edge (pixel values as they are: nothing interpolated in the camera's encoding,
    so that the response can be undone exactly); edges with too little contrast are left out.

    ``corners``: the inner corners in :func:`activesurv_imaging.calibration.find_corners`'s
    order (row by row, ``squares[0] - 1`` to a row).
    """
    img = np.asarray(image)
    if img.ndim != 2 or img.dtype != np.uint8:
        raise ValueError(f'expected an 8-bit grey image, got {img.dtype} {img.shape}')
    cols, rows = squares[0] - 1, squares[1] - 1
    pts = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if len(pts) != cols * rows:
        raise ValueError(f'expected {cols * rows} corners, got {len(pts)}')
    grid = pts.reshape(rows, cols, 2)
    a = np.concatenate([grid[:, :-1].reshape(-1, 2), grid[:-1, :].reshape(-1, 2)])
    b = np.concatenate([grid[:, 1:].reshape(-1, 2), grid[1:, :].reshape(-1, 2)])
    mid = 0.5 * (a + b)
    along = b - a
    spacing = np.linalg.norm(along, axis=1, keepdims=True)
    tangent = along / spacing
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    half = 0.35 * float(np.median(spacing))
    # A grid finer than the pixels: every pixel near the edge, at its own distance across.
    u = np.arange(-0.25, 0.25 + 1e-9, 0.5 / 12)[None, :, None] * spacing[:, :, None]
    v = np.arange(-half, half + 1e-9, 0.5)[None, None, :]
    xy = (
        mid[:, None, None, :]
        + tangent[:, None, None, :] * u[..., None]
        + normal[:, None, None, :] * v[..., None]
    )
    px = np.rint(xy).astype(np.int64)
    h, w = img.shape
    inside = (px[..., 0] >= 0) & (px[..., 1] >= 0) & (px[..., 0] < w) & (px[..., 1] < h)
    px[..., 0] = np.clip(px[..., 0], 0, w - 1)
    px[..., 1] = np.clip(px[..., 1], 0, h - 1)
    grey = img[px[..., 1], px[..., 0]].astype(np.float64).reshape(len(mid), -1)
    across = np.einsum('eijk,ek->eij', px - mid[:, None, None, :], normal).reshape(len(mid), -1)
    # Oriented dark to bright.
    dark_side = np.nanmedian(np.where(across < -0.5 * half, grey, np.nan), axis=1)
    bright_side = np.nanmedian(np.where(across > 0.5 * half, grey, np.nan), axis=1)
    flip = dark_side > bright_side
    across[flip] *= -1.0
    contrast = np.abs(bright_side - dark_side)
    keep = (contrast >= MIN_CONTRAST) & inside.reshape(len(mid), -1).all(axis=1)
    return EdgeSamples(across[keep].astype(np.float32), grey[keep].astype(np.uint8), half)


BIN = 0.25  # px: the edge profile's resolution (pixels at many sub-pixel phases fill it)


def profiles(samples: EdgeSamples, gamma: float) -> Array:
    """(E, K) each edge's profile in linear radiance (``gamma`` undone), binned at
    :data:`BIN` across the edge from ``-half`` to ``half``, normalised between its plateaus
    (the outer sixth either side); empty bins are interpolated."""
    lut = (np.arange(256, dtype=np.float64) / 255.0) ** gamma
    lin = lut[samples.grey]
    count = samples._count
    nbins = count.shape[1]
    total = np.bincount(samples._flat, lin.ravel(), minlength=count.size).reshape(-1, nbins)
    with np.errstate(invalid='ignore', divide='ignore'):
        prof = total / count
    centres = -samples.half + BIN * (np.arange(nbins) + 0.5)
    for r in np.nonzero(~np.all(count > 0, axis=1))[0]:
        ok = count[r] > 0
        prof[r] = np.interp(centres, centres[ok], prof[r, ok]) if ok.sum() > 1 else np.nan
    q = max(nbins // 6, 1)
    lo = prof[:, :q].mean(axis=1, keepdims=True)
    hi = prof[:, -q:].mean(axis=1, keepdims=True)
    return np.asarray((prof - lo) / np.maximum(hi - lo, 1e-12), dtype=np.float64)


def _crossings(level: Array, at: float) -> Array:
    """Where each rising normalised profile first reaches ``at`` (in samples, interpolated):
    the falling crossing of its complement."""
    samples = np.arange(level.shape[1], dtype=np.float64)
    return first_crossing(1.0 - level, samples, 1.0 - at)


def asymmetry(samples: EdgeSamples, gamma: float) -> Array:
    """Per edge, in bins: how far the step of the same area lies from the half-way crossing
    once ``gamma`` is undone. Zero for a point-symmetric edge; it grows with gamma."""
    level = profiles(samples, gamma)
    x50 = _crossings(level, 0.5)
    # A rising step from 0 to 1 at x has area (n - 1 - x) under it over the samples.
    step_at = (level.shape[1] - 1) - np.trapezoid(level, axis=1)
    return np.asarray(x50 - step_at, dtype=np.float64)


MIN_WIDTH = 2.0  # px from the 25 % to the 75 % crossing: sharper edges are left out


def blurred(samples: EdgeSamples) -> EdgeSamples:
    """The edges blurred enough to show the response (:data:`MIN_WIDTH`: on a ramp of a pixel
    or so the pixel's own footprint hides it): the views nearer or farther than the focus."""
    level = profiles(samples, 1.0)
    width = BIN * (_crossings(level, 0.75) - _crossings(level, 0.25))
    keep = np.isfinite(width) & (width >= MIN_WIDTH)
    return EdgeSamples(samples.across[keep], samples.grey[keep], samples.half)


def estimate_gamma(samples: Sequence[EdgeSamples]) -> GammaEstimate | None:
    """The gamma that makes the board's blurred edges symmetric (the lowest root of their
    median asymmetry in :data:`GAMMA_RANGE`), or None with too few such edges or no root."""
    views = [v for v in (blurred(s) for s in samples) if len(v)]
    total = sum(len(s) for s in views)
    if total < MIN_PROFILES:
        return None
    if total > MAX_EDGES:  # plenty: every k-th view (the estimate's cost grows with them)
        views = views[:: math.ceil(total / MAX_EDGES)]

    def median_asymmetry(g: float) -> float:
        return float(np.nanmedian(np.concatenate([asymmetry(s, g) for s in views])))

    grid = np.geomspace(*GAMMA_RANGE, 16)
    values = [median_asymmetry(float(g)) for g in grid]
    roots = [
        (float(grid[i]), float(grid[i + 1]))
        for i in range(len(grid) - 1)
        if values[i] < 0.0 <= values[i + 1]
    ]
    if not roots:
        return None
    gamma = float(brentq(median_asymmetry, *roots[0], xtol=1e-4))
    a = np.concatenate([asymmetry(s, gamma) for s in views])
    a = a[np.isfinite(a)]
    slope = (median_asymmetry(gamma * 1.05) - median_asymmetry(gamma / 1.05)) / (
        gamma * (1.05 - 1 / 1.05)
    )
    scatter = 1.253 * float(np.std(a)) / math.sqrt(max(len(a), 1))  # the median's
    spread = scatter / abs(slope) if slope else math.inf
    return GammaEstimate(gamma, len(a), spread)


@dataclass
class BoardReader:
    """Finds a board's inner corners in each view (what commissioning fits) and keeps the
    pixels across its edges, from which :meth:`gamma` estimates the camera's response, and
    the views themselves, so that the corners can be refined again in linear radiance once
    the response is known (:meth:`linearised`)."""

    squares: tuple[int, int]
    edges: list[EdgeSamples] = field(default_factory=list)
    views: list[tuple[Array, NDArray[np.uint8]]] = field(default_factory=list)
    _estimate: GammaEstimate | None = None
    _estimated_from: int = -1
    keeping: bool = True  # off: views are read but no longer kept (a check's, not the fit's)

    def __call__(self, image: ArrayLike) -> Array | None:
        corners = find_corners(image, self.squares)
        if corners is not None and self.keeping:
            with contextlib.suppress(ValueError):  # a colour frame: the corners still count
                gray = np.asarray(image)
                self.edges.append(edge_samples(gray, corners, self.squares))
                self.views.append((corners, gray))
        return corners

    def gamma(self) -> GammaEstimate | None:
        if self._estimated_from != len(self.edges):
            self._estimate = estimate_gamma(self.edges)
            self._estimated_from = len(self.edges)
        return self._estimate

    def linearised(self, corners: ArrayLike, gamma: float) -> Array:
        """``corners`` (as a view gave them, in any order the caller put them) refined again
        in that view with ``gamma`` undone: a blurred corner's saddle seen through a gamma
        curve is pulled towards its bright squares (measured, offline commissioning of cam1
        through gamma 2.2: principal point 49 px off and 0.71 px of pixel error on the raw
        frames, 8 px and 0.34 px linearised, as a linear camera's). Unchanged when no kept
        view has these corners."""
        c = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
        best, gray = math.inf, None
        for seen, image in self.views:
            if seen.shape != c.shape:
                continue
            off = min(float(np.abs(seen - c).max()), float(np.abs(seen[::-1] - c).max()))
            if off < best:
                best, gray = off, image
        if gray is None or best > 1.0:
            return c
        lut = np.clip(255.0 * (np.arange(256) / 255.0) ** gamma + 0.5, 0, 255).astype(np.uint8)
        return refine_corners(lut[gray], c)
