"""Find the circular marker in a grey image and fit its boundary ellipse.

Pipeline:

1. Contrast check: a black, saturated or flat frame has no marker.
2. Otsu threshold; outer boundaries of the bright components (``RETR_CCOMP`` top level, so a
   marker on a plate on a bright background is still found).
3. Candidates: bright blobs large enough to matter. Each is rejected with a reason if it touches
   the image border (marker partly out of view: an open contour), is outside the size range, or
   is not an ellipse (area / ellipse area, coarse fit residual). Two accepted blobs are rejected
   as "two markers": the pose of the wrong one would be confidently wrong.
4. Sub-pixel boundary: boundary pixels of the blob (every fourth) are moved along the coarse
   ellipse's normal to where the grey-level profile crosses half-way between the local marker
   and plate levels (bilinear interpolation). For a blurred step edge this is the edge itself.
   Then, at evenly spaced angles of a first fit of those (as many as the boundary has pixels),
   each edge again on a profile centred on it, its window sized from the edge's ramp (the
   lens's blur, the known streak): the half-way crossing, or across a known streak the
   area-equivalent edge (linear in the pixels, as the streak's model is). The per-edge loops
   are compiled (:mod:`activesurv_imaging.kernels`).
5. Weighted least-squares ellipse fit (:func:`activesurv_imaging.ellipse.fit_ellipse`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_imaging.ellipse import Ellipse, fit_ellipse, sampson_distances
from activesurv_imaging.errors import EllipseFitError, ImagingError
from activesurv_imaging.kernels import (
    curvature,
    evenly_spaced,
    first_pass,
    otsu,
    outward_normals,
    row_medians,
    window_pass,
)

Array = NDArray[np.float64]
Fitter = Callable[[Array], Ellipse]

_SPECK = np.ones((3, 3), np.uint8)
STRETCHES = 36  # starts of the outline stretches whose ellipses a partly hidden marker tries
MIN_VISIBLE = 0.75  # of its boundary a partly hidden marker must show to be measured
AREA_MARGIN = 4.0  # px of each area-edge profile beyond the ramp: the two levels come from it
MAX_RAMP = 60.0  # px: the longest ramp an area edge is measured across
# Profiles are sampled bilinearly (:mod:`activesurv_imaging.kernels`): bicubic, tried with
# the edges off the grid, read the physically based set worse (0.048 / 0.19 mm against 0.043 /
# 0.13) and costs more.
FIRST_PASS_STRIDE = 4  # the first pass measures every fourth boundary pixel
WINDOW_STEP = 1.0  # px: edges' windows are rounded up to it (profiles of one length at once)
# Area edges across a known streak (its model, :mod:`activesurv_imaging.streak`, is of them).
AREA_MIN_STREAK = 3.0  # px, the streak's length
ACROSS = 0.15  # |cos| of an edge normal to a streak below which the edge runs along the streak


class DetectionStatus(Enum):
    OK = 'ok'
    NOT_FOUND = 'not_found'  # nothing that could be a marker
    REJECTED = 'rejected'  # something marker-like, but not one clean ellipse (see reason)


@dataclass(frozen=True)
class DetectorConfig:
    """Detector limits (pixels unless stated).

    Attributes:
        min_semi_minor: smaller blobs are noise, not candidates.
        max_semi_major: larger ellipses are rejected as wrong size.
        min_axis_ratio: b / a below this is rejected (the marker seen almost edge-on).
        min_contrast: grey levels between marker and plate needed to trust an edge; in a dim
            frame the threshold follows the frame's own contrast (half its 1-99.9 % range).
        min_frame_contrast: a frame whose 1-99.9 % range is below this is blank (black,
            saturated, a lens cap): no marker can be measured in it.
        border_margin: a blob this close to the border is partly out of view.
        max_fill_error: |blob area / ellipse area - 1| above this is not an ellipse.
        max_coarse_residual: RMS distance of the blob contour to its coarse ellipse.
        profile_half_length: the shortest edge search range along the normal (either side).
        max_profile_half_length: the longest: the range grows with the marker (0.45 of its
            image semi-minor axis), so that a blurred edge's ramp (defocus, motion, a few to
            15 px wide) lies inside it with both grey levels beyond its ends.
        gamma: the camera's response, ``grey = 255 (radiance / full scale)^(1 / gamma)``; the
            profiles are linearised first (a blurred edge's half-way crossing in radiance is
            the edge, in grey levels it is not). 1: a linear camera.
        subpixel: refine edges to sub-pixel (off: the boundary pixels are used as they are).
        streak_length: px the marker moved over the exposure, when known: the search range
            covers the streak's ramp (half of it plus 8 px either side, up to 0.9 of the
            semi-minor axis), so that both grey levels lie beyond the ramp's ends however far
            the coarse boundary (a threshold across a long ramp) lies from the edge.
        near_gate: px from the expected position within which one of several markers is taken.
        streak_angle: rad, the streak's direction in the image (with ``streak_length``): its
            share of each edge's ramp is not taken for the lens's blur.
        area_edges: measure each edge again as its area-equivalent edge, on a profile centred on
            it over the ramp's width (off: the half-way crossings alone, biased inwards by noise
            on long ramps).
    """

    min_semi_minor: float = 4.0
    max_semi_major: float = 400.0
    min_axis_ratio: float = 0.12
    min_contrast: float = 40.0
    min_frame_contrast: float = 20.0
    border_margin: int = 2
    max_fill_error: float = 0.08
    max_coarse_residual: float = 1.5
    profile_half_length: float = 4.0
    max_profile_half_length: float = 16.0
    gamma: float = 1.0
    subpixel: bool = True
    near_gate: float = 60.0
    streak_length: float = 0.0
    streak_angle: float = 0.0
    area_edges: bool = True


@dataclass(frozen=True)
class Detection:
    """Outcome of :func:`detect_marker_detailed`.

    Attributes:
        status: OK, NOT_FOUND or REJECTED.
        reason: why not OK (empty when OK).
        ellipse: the fitted ellipse when OK.
        edge_points: (N, 2) boundary points the ellipse was fitted to.
        candidates: how many marker-sized bright blobs were seen.
        blur_sigma: px, the isotropic blur found across the edge (lens, focus, pixel).
        visible: the fraction of the marker's boundary measured (below 1: the marker was
            partly hidden or ran into something as bright, and its ellipse was fitted to the
            arc that showed: :func:`_partly_hidden`).
    """

    status: DetectionStatus
    reason: str = ''
    ellipse: Ellipse | None = None
    edge_points: Array = field(default_factory=lambda: np.zeros((0, 2)))
    candidates: int = 0
    blur_sigma: float = 0.0
    visible: float = 1.0


def as_gray8(image: ArrayLike) -> NDArray[np.uint8]:
    """Check and return an 8-bit single-channel image (3-channel images are converted).

    Raises:
        ImagingError: for anything that is not an 8-bit image.
    """
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise ImagingError(f'expected an 8-bit image, got dtype {img.dtype}')
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    elif img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim != 2 or img.shape[0] < 8 or img.shape[1] < 8:
        raise ImagingError(f'expected a grey image of at least 8x8 pixels, got {img.shape}')
    return np.ascontiguousarray(img)


def _coarse(contour: NDArray[Any]) -> Ellipse | None:
    return _cv_ellipse(contour) if len(contour) >= 5 else None


def _outward_normals(ell: Ellipse, pts: Array) -> Array:
    cx, cy = ell.center
    return outward_normals(ell.conic(), float(cx), float(cy), np.ascontiguousarray(pts))


def subpixel_edges(
    image: NDArray[np.uint8], boundary: Array, coarse: Ellipse, config: DetectorConfig
) -> tuple[Array, float]:
    """Move boundary pixels to the half-way crossing of the grey-level profile across the edge.

    The profile runs along the coarse ellipse's normal over a range that grows with the marker
    (:class:`DetectorConfig`), in linear radiance (the camera's ``gamma`` undone); the marker
    and plate levels are the medians of its inner and outer quarters, beyond a blurred edge's
    ramp, so that the crossing is the edge whatever the blur. Returns the points and the
    isotropic blur's variance found across the edge (px^2).
    """
    # Measured again off the grid, the edges need the first pass only for a first fit, the
    # blur and the gaps: every fourth boundary pixel tells them as well (at least 32 of them).
    stride = max(min(FIRST_PASS_STRIDE, len(boundary) // 32), 1) if config.area_edges else 1
    boundary = np.ascontiguousarray(boundary[::stride])
    normals = _outward_normals(coarse, boundary)
    half = min(
        max(0.45 * coarse.semi_axes[1], config.profile_half_length),
        max(config.max_profile_half_length, config.profile_half_length),
    )
    if config.streak_length > 0.0:  # the streak's ramp and a margin either side of it
        half = max(half, min(0.5 * config.streak_length + 8.0, 0.9 * coarse.semi_axes[1]))
    step = 0.25 if half <= 6.0 else 0.5
    lut = _response_lut(config.gamma)
    t_all, sig2 = first_pass(image, lut, boundary, normals, half, step, _linear_contrast(config))
    idx = np.nonzero(np.isfinite(t_all))[0]
    t = t_all[idx]
    # A disc blurred by an isotropic blur of variance s2 (defocus, the pixel) has its half-way
    # contour inside the disc by curvature x s2 / 2. Motion blur adds variance along its
    # direction only, and moves no half-way point along it: the isotropic part is the least
    # variance found around the marker.
    var = 0.0
    if not len(idx):
        return np.zeros((0, 2)), var
    swept = config.streak_length * np.abs(
        normals[idx] @ np.array([math.cos(config.streak_angle), math.sin(config.streak_angle)])
    )
    var, widest = _blur_variance(sig2[idx], swept)
    boundary, normals = boundary[idx], normals[idx]
    if config.area_edges:
        # The window holds the longest ramp: a known streak's, or the widest blur found (an
        # unknown motion's streak, a tilted marker's defocus).
        area = config.streak_length >= AREA_MIN_STREAK
        ramp: float | Array = (
            max(0.5 * config.streak_length + 2.5 * math.sqrt(var), 2.5 * math.sqrt(widest)) + 1.0
        )
        if area:
            # Each edge's own ramp: the streak sweeps along its normal by swept (px), so an
            # edge across the motion is as short as a still one's; a window as long as the
            # streak's would sum the noise of pixels that hold nothing of that edge.
            ramp = 0.5 * swept + 2.5 * math.sqrt(var) + 1.0
        at, normals, kept = _off_the_grid(boundary + normals * t[:, None], normals, stride)
        if kept is not None and not np.isscalar(ramp):
            ramp = np.asarray(ramp)[kept]
        dt, keep = _edges_again(image, at, normals, ramp, config, area)
        boundary, normals, t = at[keep], normals[keep], dt
    # The area-equivalent edge of a blurred disc is pulled in as the half-way contour is.
    t += 0.5 * _curvature(coarse, boundary) * var
    return np.asarray(boundary + normals * t[:, None], dtype=np.float64), var


def _off_the_grid(
    at: Array, normals: Array, per_edge: int = 1
) -> tuple[Array, Array, NDArray[np.intp] | None]:
    """Where to measure each edge again: on a first fit of the first pass's edges, at evenly
    spaced angles of it (``per_edge`` for each edge), where it has edges (a gap stays a gap).

    The first pass measures one edge per boundary pixel, at the pixel's angle from the centre:
    so the edges' places across the pixel grid follow the grid, and an interpolated profile's
    error depends on that place (up to ~0.08 px on a sharp edge). Averaged over the boundary
    pixels' places it does not cancel: a sharp marker read 0.015 px large (0.07 mm too near at
    0.55 m). At evenly spaced angles the places fall anywhere across the pixels and it does.
    Returns the points (on the fit, their offset 0), their outward normals, and for each the
    index of the first-pass edge nearest in angle (to carry per-edge values); the input as it
    is (and None) when too few edges or no ellipse fits.
    """
    n = len(at)
    if n < 16:
        return at, normals, None
    try:
        e = fit_ellipse(at, iterations=0)
    except EllipseFitError:
        return at, normals, None
    (a, b), (cx, cy) = e.semi_axes, e.center
    pts, nrm, near = evenly_spaced(at, float(cx), float(cy), a, b, e.angle, n * per_edge)
    return pts, nrm, near


def _edges_again(
    image: NDArray[np.uint8],
    centres: Array,
    normals: Array,
    ramp: float | Array,
    config: DetectorConfig,
    area: bool,
) -> tuple[Array, NDArray[np.bool_]]:
    """Each edge again, on a profile centred on it over a window sized from the edge's ramp
    (``ramp``: px either side, from the blur and the streak) with the marker's and the plate's
    levels from beyond its ends: the first search ran from the coarse boundary, which on a long
    ramp or beside something bright can lie pixels off the edge, its levels taken on the ramp.

    ``area``: the area-equivalent edge (the step holding the same light between the two levels),
    else the half-way crossing. The area is linear in the pixels: on a streak's long ramp noise
    pulls a first crossing inwards (a dip below the mid level comes earlier than a rise above it
    later) and the area does not move, and it is what the streak's model predicts; on a steep
    edge (or a defocused one: measured) the crossing is the less noisy. Returns each point's
    offset along its normal (px) and which points held. ``ramp`` may differ edge by edge.
    """
    n = len(centres)
    if np.ndim(ramp) == 0:
        halves = np.full(n, min(float(ramp), MAX_RAMP) + AREA_MARGIN)
    else:  # rounded up to whole steps of WINDOW_STEP px: a few groups, each one array
        ramps = np.minimum(np.asarray(ramp, dtype=np.float64), MAX_RAMP)
        halves = np.ceil(ramps / WINDOW_STEP) * WINDOW_STEP + AREA_MARGIN
    t, keep = window_pass(
        image,
        _response_lut(config.gamma),
        centres,
        normals,
        halves,
        AREA_MARGIN,
        area,
        _linear_contrast(config),
    )
    return t[keep], keep


def _blur_variance(raw: Array, swept: Array | None = None) -> tuple[float, float]:
    """The marker's isotropic blur variance across its edge (px^2). Each profile's blur comes
    from where it crosses 75 % and 25 % of the way from the marker's level to the plate's (for
    a Gaussian blur of sigma they lie 1.349 sigma apart; unlike the slope's moments they do not
    see the noise of the flat parts): ``raw``, its square per edge (NaN where a crossing is
    missing), less the known streak's share (``swept``: px of the streak along each profile; a
    uniform ramp of that length crosses them half of it apart); the medians of 16 arcs of the
    boundary (it comes in contour order) smooth the noise, and the least of them is the
    isotropic part (motion blur adds to some directions only). Also the greatest of them, the
    streak's share kept: the widest ramp around the marker."""
    share = np.zeros_like(raw) if swept is None else (0.5 * swept / 1.349) ** 2
    arcs = 16 if len(raw) >= 64 else 1
    usable = len(raw) // arcs * arcs
    if usable == 0:
        return 0.0, 0.0
    per_arc = row_medians(np.vstack([raw[:usable], share[:usable]]).reshape(2 * arcs, -1))
    wide, streak = per_arc[:arcs], per_arc[arcs:]
    iso = wide - streak
    if swept is not None and float(np.max(swept)) >= AREA_MIN_STREAK:
        # Along the streak its ramp hides the lens's blur: the edges across it tell (those
        # within ~9 degrees of it, where it sweeps under 15 % of its length along the profile).
        across = (swept < ACROSS * float(np.max(swept))) & np.isfinite(raw)
        if int(across.sum()) >= 8:
            iso = np.array([float(np.median(raw[across] - share[across]))])
    iso, wide = iso[np.isfinite(iso)], wide[np.isfinite(wide)]
    return (
        max(float(iso.min()), 0.0) if len(iso) else 0.0,
        max(float(wide.max()), 0.0) if len(wide) else 0.0,
    )


def first_crossing(level: Array, steps: Array, at: float) -> Array:
    """Where each normalised profile first falls below ``at`` (from the inside), or NaN."""
    below = level < at
    first = np.argmax(below, axis=1)
    ok = below.any(axis=1) & (first > 0)
    rows = np.arange(len(level))
    f = np.maximum(first, 1)
    v0, v1 = level[rows, f - 1], level[rows, f]
    frac = np.clip((v0 - at) / np.maximum(v0 - v1, 1e-9), 0.0, 1.0)
    t = steps[f - 1] + (steps[1] - steps[0]) * frac
    return np.where(ok, t, np.nan)


def _curvature(ell: Ellipse, pts: Array) -> Array:
    """The ellipse's curvature (1/px) at the points nearest ``pts`` (by their angle)."""
    (a, b), (cx, cy) = ell.semi_axes, ell.center
    return curvature(float(cx), float(cy), a, b, ell.angle, np.ascontiguousarray(pts))


@functools.lru_cache(maxsize=16)
def _response_lut(gamma: float) -> Array:
    """Linear radiance of each grey level under ``gamma`` (a camera has one: made once)."""
    return np.asarray(255.0 * (np.arange(256, dtype=np.float64) / 255.0) ** gamma)


def _linear_contrast(config: DetectorConfig) -> float:
    """``min_contrast`` in linear radiance: the least contrast against a black plate."""
    if config.gamma == 1.0:
        return config.min_contrast
    return float(255.0 * (config.min_contrast / 255.0) ** config.gamma)


def detect_marker_detailed(
    image: ArrayLike,
    config: DetectorConfig | None = None,
    fitter: Fitter | None = None,
    near: ArrayLike | None = None,
    near_gate: float | None = None,
) -> Detection:
    """Detect the marker and say why not when there is none.

    Args:
        image: 8-bit grey image (3-channel is converted).
        config: detector limits.
        fitter: ellipse fitter for the boundary points (default: the weighted fit of eq. 3-4);
            the benchmark swaps in OpenCV's fitters here.
        near: (u, v) where the marker is expected (several objects in view): the marker
            nearest there, if within ``near_gate`` px (default the config's); None: one
            marker or none.

    Raises:
        ImagingError: if ``image`` is not an 8-bit image.
    """
    cfg = DetectorConfig() if config is None else config
    img = as_gray8(image)
    levels = _levels(img)
    found = _marker_blobs(img, cfg, levels)
    if isinstance(found, Detection):
        return found
    cfg = _for_frame(levels, cfg)
    accepted, reasons, candidates = found
    if accepted and near is not None:
        gate = cfg.near_gate if near_gate is None else near_gate
        uv = np.asarray(near, dtype=np.float64).reshape(2)
        d = [float(np.hypot(*(c.center - uv))) for _, c in accepted]
        j = int(np.argmin(d))
        if d[j] > gate:
            return Detection(
                DetectionStatus.REJECTED,
                f'{len(accepted)} marker(s) in view, none within {gate:.0f} px of where the '
                f"demanded one should be ({uv[0]:.0f}, {uv[1]:.0f}): another object's",
                candidates=candidates,
            )
        accepted = [accepted[j]]
    if len(accepted) > 1:
        centres = ', '.join(f'({c.center[0]:.0f}, {c.center[1]:.0f})' for _, c in accepted)
        return Detection(
            DetectionStatus.REJECTED,
            f'{len(accepted)} markers in view at {centres}; expected one',
            candidates=candidates,
        )
    if not accepted:
        if near is not None and reasons:
            gate = cfg.near_gate if near_gate is None else near_gate
            arc = _partly_hidden(img, cfg, np.asarray(near, dtype=np.float64).reshape(2), gate)
            if arc is not None:
                found_arc = _fit_blob(img, arc[:2], cfg, fitter, candidates, robust=True)
                if found_arc.status is DetectionStatus.OK:
                    return replace(found_arc, visible=arc[2])
        if reasons:
            return Detection(DetectionStatus.REJECTED, reasons[0], candidates=candidates)
        return Detection(
            DetectionStatus.NOT_FOUND, 'no marker-sized bright region', candidates=candidates
        )
    return _fit_blob(img, accepted[0], cfg, fitter, candidates)


def detect_markers(
    image: ArrayLike, config: DetectorConfig | None = None, fitter: Fitter | None = None
) -> list[Detection]:
    """Every marker in the image (the overhead camera with several objects on the table):
    one detection each, OK or why its fit failed; none when there is no marker."""
    cfg = DetectorConfig() if config is None else config
    img = as_gray8(image)
    levels = _levels(img)
    found = _marker_blobs(img, cfg, levels)
    if isinstance(found, Detection):
        return []
    cfg = _for_frame(levels, cfg)
    accepted, _, candidates = found
    return [_fit_blob(img, blob, cfg, fitter, candidates) for blob in accepted]


def _levels(img: NDArray[np.uint8]) -> tuple[int, int, int]:
    """The frame's 1 % and 99.9 % grey levels and its Otsu threshold, from one 256-bin
    histogram (OpenCV's: a full-frame sort costs milliseconds, numpy's bincount one) of every
    other row: a frame's statistics at half the cost."""
    rows = img[::2] if img.shape[0] >= 64 else img
    hist = cv2.calcHist([rows], [0], None, [256], [0, 256]).ravel().astype(np.float64)
    cdf = np.cumsum(hist) / rows.size
    lo, hi = int(np.searchsorted(cdf, 0.01)), int(np.searchsorted(cdf, 0.999))
    return lo, hi, otsu(hist)


def _for_frame(levels: tuple[int, int, int], cfg: DetectorConfig) -> DetectorConfig:
    """The limits for this frame (its 1 % and 99.9 % grey ``levels``): an edge's contrast
    threshold follows a dim frame's own contrast (unchanged in a well-exposed one)."""
    lo, hi, _ = levels
    edge = min(cfg.min_contrast, 0.5 * (hi - lo))
    return cfg if edge == cfg.min_contrast else replace(cfg, min_contrast=edge)


def _bright(img: NDArray[np.uint8], otsu_level: int | None = None) -> NDArray[np.uint8]:
    """The frame's bright regions: Otsu's threshold (``otsu_level`` when known), its noise
    specks opened away (they became hundreds of contours: a noisy frame's contour search
    took 4 ms)."""
    if otsu_level is None:
        _, binary = cv2.threshold(img, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    else:
        _, binary = cv2.threshold(img, otsu_level, 255, cv2.THRESH_BINARY)
    return np.asarray(cv2.morphologyEx(binary, cv2.MORPH_OPEN, _SPECK), dtype=np.uint8)


def _marker_blobs(
    img: NDArray[np.uint8], cfg: DetectorConfig, levels: tuple[int, int, int]
) -> Detection | tuple[list[tuple[NDArray[Any], Ellipse]], list[str], int]:
    """The bright blobs that pass as markers, the reasons the others did not, and how many
    there were; or a Detection saying why there can be none (``levels``: the frame's 1 % and
    99.9 % grey levels and its Otsu threshold)."""
    lo, hi, otsu_level = levels
    if hi - lo < cfg.min_frame_contrast:
        return Detection(
            DetectionStatus.NOT_FOUND,
            f'no contrast in the image (grey levels {lo:.0f}..{hi:.0f}): '
            'black, saturated or blank frame',
        )
    binary = _bright(img, otsu_level)
    contours, hierarchy = cv2.findContours(binary, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hierarchy is None:
        return Detection(DetectionStatus.NOT_FOUND, 'no bright region in the image')
    h, w = img.shape
    min_area = math.pi * cfg.min_semi_minor**2
    accepted: list[tuple[NDArray[Any], Ellipse]] = []
    reasons: list[str] = []
    candidates = 0
    # A contour of fewer points cannot enclose min_area (its steps are at most sqrt(2) px, and
    # no outline shorter than a circle's encloses as much): noise specks, skipped unmeasured.
    # Holes (not the outer boundary of a bright blob) and specks are sorted out at once: a
    # textured frame has hundreds of contours.
    min_points = math.sqrt(4.0 * math.pi * min_area) / math.sqrt(2.0)
    lengths = np.fromiter(map(len, contours), dtype=np.intp, count=len(contours))
    outer = np.nonzero((hierarchy[0][:, 3] == -1) & (lengths >= min_points))[0]
    for i in outer.tolist():
        contour = contours[i]
        area = cv2.contourArea(contour)
        if area < min_area:
            continue  # speck of noise
        candidates += 1
        pts = contour.reshape(-1, 2)
        m = cfg.border_margin
        x, y, bw, bh = cv2.boundingRect(contour)
        if x < m or y < m or x + bw - 1 >= w - m or y + bh - 1 >= h - m:
            reasons.append(
                'a bright region touches the image border (marker partly out of '
                'view, or background)'
            )
            continue
        coarse = _coarse(contour)
        if coarse is None:
            reasons.append('a bright region has no ellipse fit')
            continue
        a, b = coarse.semi_axes
        if a > cfg.max_semi_major or b < cfg.min_semi_minor:
            reasons.append(
                f'wrong size: semi-axes {a:.0f} x {b:.0f} px outside '
                f'{cfg.min_semi_minor:.0f}..{cfg.max_semi_major:.0f} px'
            )
            continue
        if b / a < cfg.min_axis_ratio:
            reasons.append(f'seen too obliquely: axis ratio {b / a:.2f} < {cfg.min_axis_ratio}')
            continue
        fill = area / coarse.area
        if abs(fill - 1.0) > cfg.max_fill_error:
            reasons.append(f'not an ellipse: blob fills {fill:.2f} of its ellipse')
            continue
        rms = float(np.sqrt(np.mean(sampson_distances(coarse.conic(), pts) ** 2)))
        if rms > cfg.max_coarse_residual:
            reasons.append(f'not an ellipse: contour residual {rms:.2f} px')
            continue
        accepted.append((contour, coarse))
    return accepted, reasons, candidates


def _partly_hidden(
    img: NDArray[np.uint8], cfg: DetectorConfig, near: Array, gate: float
) -> tuple[NDArray[Any], Ellipse, float] | None:
    """The marker at ``near`` when its blob failed as a whole (it touches the border or is not
    one ellipse: the marker partly hidden behind something, or joined to something as bright):
    the ellipse most of the blob's outline lies on (tried: the ellipses of stretches of the
    outline, a sixth to a third of it long; on it: within 1.5 px), its centre within ``gate``
    px of ``near``, at least ``MIN_VISIBLE`` of its boundary shown. Returns the outline's
    points on it (in contour order), that ellipse and the fraction of its boundary they cover;
    None if there is no such marker."""
    binary = _bright(img)
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    point = (float(near[0]), float(near[1]))
    hit = [c for c in contours if len(c) >= 20 and cv2.pointPolygonTest(c, point, False) >= 0]
    if not hit:
        return None
    contour = hit[0].reshape(-1, 2)
    h, w = img.shape
    m = cfg.border_margin + 1
    inside = (
        (contour[:, 0] >= m)
        & (contour[:, 1] >= m)
        & (contour[:, 0] < w - m)
        & (contour[:, 1] < h - m)
    )
    pts = contour.astype(np.float64)
    n = len(pts)
    if int(inside.sum()) < 20:
        return None
    # Hypotheses: the ellipses of stretches of the outline (the visible arc is one stretch of
    # it, the rest is what hides or joins it), scored by how much of the outline lies on them.
    best: tuple[int, Ellipse] | None = None
    for span in (n // 6, n // 4, n // 3):
        for start in range(0, n, max(n // STRETCHES, 1)):
            idx = np.arange(start, start + span) % n
            idx = idx[inside[idx]]
            if len(idx) < 10:
                continue
            e = _cv_ellipse(pts[idx].astype(np.float32))
            if e is None or not _marker_sized(e, cfg):
                continue
            if float(np.hypot(*(e.center - near))) > gate:
                continue
            score = int(np.count_nonzero(inside & (sampson_distances(e.conic(), pts) < 1.5)))
            if best is None or score > best[0]:
                best = (score, e)
    if best is None:
        return None
    ellipse = best[1]
    for _ in range(2):  # refit to all its inliers
        on = inside & (sampson_distances(ellipse.conic(), pts) < 1.5)
        refit = _cv_ellipse(pts[on].astype(np.float32)) if on.sum() >= 5 else None
        if refit is None or not _marker_sized(refit, cfg):
            return None
        ellipse = refit
    on = inside & (sampson_distances(ellipse.conic(), pts) < 1.5)
    d = pts[on] - ellipse.center
    ca, sa = math.cos(ellipse.angle), math.sin(ellipse.angle)
    phi = np.arctan2(-sa * d[:, 0] + ca * d[:, 1], ca * d[:, 0] + sa * d[:, 1])
    bins = np.unique(np.floor((phi + math.pi) / (2.0 * math.pi) * 72.0).astype(int))
    visible = len(bins) / 72.0
    if visible < MIN_VISIBLE or float(np.hypot(*(ellipse.center - near))) > gate:
        return None
    return contour[on].reshape(-1, 1, 2), ellipse, visible


def _cv_ellipse(points: NDArray[Any]) -> Ellipse | None:
    """OpenCV's ellipse through ``points`` (at least five; a contour or float32), or None."""
    (cx, cy), (w, h), ang = cv2.fitEllipse(points)
    if not (w > 0 and h > 0 and math.isfinite(cx) and math.isfinite(cy)):
        return None
    a, b = 0.5 * max(w, h), 0.5 * min(w, h)
    angle = math.radians(ang) + (0.0 if w >= h else math.pi / 2)
    return Ellipse(np.array([cx, cy]), (a, b), angle % math.pi)


def _marker_sized(e: Ellipse, cfg: DetectorConfig) -> bool:
    a, b = e.semi_axes
    return cfg.min_semi_minor <= b and a <= cfg.max_semi_major and b / a >= cfg.min_axis_ratio


def _fit_blob(
    img: NDArray[np.uint8],
    blob: tuple[NDArray[Any], Ellipse],
    cfg: DetectorConfig,
    fitter: Fitter | None,
    candidates: int,
    robust: bool = False,
) -> Detection:
    """The weighted ellipse fit of one marker blob's sub-pixel edges (``robust``: the edges
    farther than 3 MADs off a first fit are dropped, as where a partly hidden marker's arc meets
    what hides it)."""
    fit: Fitter = fit_ellipse if fitter is None else fitter
    contour, coarse = blob
    boundary = contour.reshape(-1, 2).astype(np.float64)
    edges, var = subpixel_edges(img, boundary, coarse, cfg) if cfg.subpixel else (boundary, 0.0)
    if robust and len(edges) >= 12:
        try:
            d = sampson_distances(fit_ellipse(edges, iterations=0).conic(), edges)
        except EllipseFitError:
            d = np.zeros(len(edges))
        mad = float(np.median(np.abs(d - np.median(d)))) + 1e-3
        edges = edges[d <= float(np.median(d)) + 3.0 * 1.4826 * mad]
    if len(edges) < max(12, len(boundary) // 2):
        return Detection(
            DetectionStatus.REJECTED,
            f'weak edges: only {len(edges)} of {len(boundary)} boundary points '
            'have enough contrast',
            candidates=candidates,
        )
    try:
        ellipse = fit(edges)
    except EllipseFitError as exc:
        return Detection(
            DetectionStatus.REJECTED, f'ellipse fit failed: {exc}', candidates=candidates
        )
    return Detection(DetectionStatus.OK, '', ellipse, edges, candidates, math.sqrt(var))


def detect_marker(image: ArrayLike) -> Ellipse | None:
    """The marker's boundary ellipse in an 8-bit grey image, or None if there is no one marker.

    Use :func:`detect_marker_detailed` for the reason.
    """
    det = detect_marker_detailed(image)
    return det.ellipse if det.status is DetectionStatus.OK else None
