"""The physically based test set (issue 33, item 5): load it, measure it, ours and OpenCV's.

The set is rendered once by ``scripts/render_photoreal.py`` (Mitsuba 3, a development tool) and
stored with its truth (``truth.json``); neither the tests nor the bench need the renderer. Each
view is measured as a run measures it: given the predicted normal (a few degrees off) and the
predicted image position (a few pixels off), the camera's gamma and, for a moving object, the
streak of its predicted velocity over the exposure.

The OpenCV baseline is the plain pipeline a lab would write first: Gaussian blur, Canny edges
(thresholds from Otsu's), the contours' ellipses (``cv2.fitEllipse``), the one nearest the
predicted position, and the same circle-pose solution as ours.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import angle_between
from activesurv_imaging.circle_pose import choose_pose, circle_poses
from activesurv_imaging.ellipse import Ellipse
from activesurv_imaging.errors import CirclePoseError
from activesurv_imaging.marker_pose import MeasurementStatus, measure_marker

NEAR_GATE = 40.0  # px: how far from the predicted position a marker is taken


class PhotorealError(ValueError):
    """A test set that cannot be read."""


@dataclass(frozen=True)
class View:
    """One stored image with what a run would know and the truth (camera frame)."""

    name: str
    case: str
    image: NDArray[np.uint8]
    camera: CameraModel
    centre: NDArray[np.float64]  # the disc's centre, camera frame (m)
    normal: NDArray[np.float64]
    predicted_normal: NDArray[np.float64]
    near: NDArray[np.float64]  # predicted image position (px)
    radius: float
    gamma: float
    streak: NDArray[np.float64]  # px over the exposure, from the predicted velocity


@dataclass(frozen=True)
class Reading:
    """One view measured: errors (None when not measured) and the time it took."""

    view: View
    centre_error: float | None  # m
    normal_error: float | None  # deg
    seconds: float
    reason: str = ''


def load_set(directory: Path | str) -> tuple[list[View], dict[str, Any]]:
    """The views of a stored set and its metadata (renderer, sensor, convention check).

    Raises:
        PhotorealError: if the directory, its truth or an image is missing or unreadable.
    """
    d = Path(directory)
    try:
        doc = json.loads((d / 'truth.json').read_text())
    except (OSError, ValueError) as exc:
        raise PhotorealError(f'{d}: no readable truth.json ({exc})') from exc
    views = []
    for k, e in enumerate(doc.get('images', []) if isinstance(doc, dict) else []):
        try:
            views.append(_view(d, e))
        except PhotorealError:
            raise
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise PhotorealError(f'{d}/truth.json: image {k}: {exc!r}') from exc
    if not views:
        raise PhotorealError(f'{d}/truth.json lists no images')
    meta = {k: v for k, v in doc.items() if k != 'images'}
    return views, meta


def _view(d: Path, e: dict[str, Any]) -> View:
    img = cv2.imread(str(d / e['image']), cv2.IMREAD_UNCHANGED)
    if img is None or img.dtype != np.uint8 or img.ndim != 2:
        raise PhotorealError(f'{d / e["image"]}: missing, or not an 8-bit grey image')
    c = e['camera']
    camera = CameraModel(int(c['width']), int(c['height']), np.array(c['K']), np.zeros(5))
    R = np.array(c['R_world_camera'], dtype=np.float64)
    t = np.array(c['t_world_camera'], dtype=np.float64)
    return View(
        e['image'],
        e['case'],
        np.asarray(img, dtype=np.uint8),
        camera,
        R.T @ (np.array(e['centre']) - t),
        R.T @ np.array(e['normal']),
        R.T @ np.array(e['predicted_normal']),
        np.array(e['predicted_uv'], dtype=np.float64),
        float(e['radius']),
        float(e['gamma']),
        np.array(e['streak_px'], dtype=np.float64),
    )


def _errors(view: View, centre: NDArray[np.float64], normal: NDArray[np.float64]) -> Reading:
    return Reading(
        view,
        float(np.linalg.norm(centre - view.centre)),
        math.degrees(angle_between(normal, view.normal)),
        0.0,
    )


def measure_ours(view: View) -> Reading:
    """Our imager, as a run calls it."""
    t0 = time.perf_counter()
    m = measure_marker(
        view.image,
        view.camera,
        view.radius,
        prior_normal=view.predicted_normal,
        near=view.near,
        near_gate=NEAR_GATE,
        gamma=view.gamma,
        streak=view.streak if np.any(view.streak) else None,
    )
    dt = time.perf_counter() - t0
    if m.status is not MeasurementStatus.OK or m.pose is None:
        return Reading(view, None, None, dt, m.reason)
    r = _errors(view, m.pose.center, m.pose.normal)
    return Reading(view, r.centre_error, r.normal_error, dt)


def opencv_ellipse(image: NDArray[np.uint8], near: NDArray[np.float64]) -> Ellipse | None:
    """The plain OpenCV pipeline's marker ellipse nearest ``near`` (None: none found)."""
    blurred = cv2.GaussianBlur(image, (5, 5), 0)
    otsu, _ = cv2.threshold(blurred, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    edges = cv2.Canny(blurred, 0.5 * otsu, otsu)
    contours, _ = cv2.findContours(edges, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    best: tuple[float, Ellipse] | None = None
    for c in contours:
        if len(c) < 30:
            continue
        (cx, cy), (w, h), ang = cv2.fitEllipse(c)
        if min(w, h) < 10.0 or not math.isfinite(cx):
            continue
        if math.hypot(cx - near[0], cy - near[1]) > NEAR_GATE:
            continue
        a, b = 0.5 * max(w, h), 0.5 * min(w, h)
        angle = math.radians(ang) + (0.0 if w >= h else math.pi / 2)
        e = Ellipse(np.array([cx, cy], dtype=np.float64), (a, b), angle % math.pi)
        # An ellipse's contour, not the plate's square edge: its points lie on the fit.
        pts = c.reshape(-1, 2).astype(np.float64) - e.center
        ca, sa = math.cos(e.angle), math.sin(e.angle)
        x, y = pts @ np.array([ca, sa]), pts @ np.array([-sa, ca])
        residual = float(np.median(np.abs(np.hypot(x / a, y / b) - 1.0))) * 0.5 * (a + b)
        if residual > 1.0:
            continue
        if best is None or a > best[0]:  # the disc's outer boundary: the largest of them
            best = (a, e)
    return None if best is None else best[1]


def measure_opencv(view: View) -> Reading:
    """The OpenCV baseline (module doc) on the same view."""
    t0 = time.perf_counter()
    ellipse = opencv_ellipse(view.image, view.near)
    if ellipse is None:
        return Reading(view, None, None, time.perf_counter() - t0, 'no ellipse near')
    try:
        poses = circle_poses(ellipse, view.camera.K, view.radius)
    except CirclePoseError as exc:
        return Reading(view, None, None, time.perf_counter() - t0, str(exc))
    chosen, _ = choose_pose(poses, view.predicted_normal)
    dt = time.perf_counter() - t0
    r = _errors(view, poses[chosen].center, poses[chosen].normal)
    return Reading(view, r.centre_error, r.normal_error, dt)


def summary(readings: Sequence[Reading]) -> dict[str, Any]:
    """Per case and overall: measured fraction, centre error median / p90 (mm), normal
    error median (deg), median ms a frame."""

    def stats(rs: Sequence[Reading]) -> dict[str, Any]:
        c = [r.centre_error for r in rs if r.centre_error is not None]
        n = [r.normal_error for r in rs if r.normal_error is not None]
        return {
            'detected': round(len(c) / len(rs), 3) if rs else 0.0,
            'median_mm': round(1e3 * statistics.median(c), 4) if c else None,
            'p90_mm': round(1e3 * float(np.percentile(c, 90)), 4) if c else None,
            'normal_median_deg': round(statistics.median(n), 4) if n else None,
            'ms_per_frame': round(1e3 * statistics.median(r.seconds for r in rs), 2)
            if rs
            else None,
        }

    cases = sorted({r.view.case for r in readings})
    out = {case: stats([r for r in readings if r.view.case == case]) for case in cases}
    out['all'] = stats(readings)
    return out
