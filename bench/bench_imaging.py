"""Imaging benchmarks: pose accuracy on rendered images, speed, and ours vs OpenCV's fitters.

200 random views with the default dynamic camera: marker 0.45-0.75 m away, bearing 15-60 deg,
aimed within a few mm of the marker. The same sub-pixel edge points feed every fitter and the
same circle-pose code, so only the ellipse fit differs.
"""

from __future__ import annotations

import math
import statistics
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.geometry import angle_between, rotation_between
from activesurv_imaging.ellipse import Ellipse
from activesurv_imaging.marker_pose import MeasurementStatus, measure_marker
from activesurv_sim.render import Plate, Renderer, Scene, look_at, render

N_VIEWS = 200
RADIUS = 0.0125


def _cv_fitter(fn: Any) -> Any:
    def fit(points: np.ndarray) -> Ellipse:
        (cx, cy), (w, h), ang = fn(points.astype(np.float32))
        a, b = 0.5 * max(w, h), 0.5 * min(w, h)
        angle = math.radians(ang) + (0.0 if w >= h else math.pi / 2)
        return Ellipse(np.array([cx, cy], dtype=np.float64), (a, b), angle % math.pi)

    return fit


FITTERS = {
    'weighted_ls': None,
    'cv_fitEllipse': _cv_fitter(cv2.fitEllipse),
    'cv_fitEllipseAMS': _cv_fitter(cv2.fitEllipseAMS),
    'cv_fitEllipseDirect': _cv_fitter(cv2.fitEllipseDirect),
}


def _views(rng: np.random.Generator) -> list[tuple[np.ndarray, Any, np.ndarray, np.ndarray]]:
    cam = dynamic_camera()
    marker = np.array([0.2, 0.1, 0.05])
    normal = np.array([0.0, -1.0, 0.0])
    out = []
    for _ in range(N_VIEWS):
        d = rng.uniform(0.45, 0.75)
        bearing = math.radians(rng.uniform(15.0, 60.0))
        az = rng.uniform(-math.pi, math.pi)
        tilt = rotation_between(normal, [math.cos(az), -1.0 / math.tan(bearing), math.sin(az)])
        eye = marker + d * (tilt @ normal)
        T = look_at(eye, marker + rng.normal(0.0, 0.004, 3))
        img = render(cam, T, Scene((Plate.disc(marker, normal, RADIUS),)), rng=rng)
        Tinv = T.inverse()
        out.append((img, T, Tinv.apply(marker), Tinv.rotate(normal)))
    return out


PHOTOREAL = Path(__file__).resolve().parents[1] / 'test' / 'data' / 'photoreal'


def photoreal() -> dict[str, Any]:
    """The physically based set (``scripts/render_photoreal.py``), per case and overall: ours
    and, under ``opencv``, the plain OpenCV pipeline on the same views (issue 33's goals: every
    view measured, median <= 0.1 mm overall and <= 0.2 mm per case, p90 <= 0.4 mm)."""
    from activesurv_studies.photoreal import load_set, measure_opencv, measure_ours, summary

    views, meta = load_set(PHOTOREAL)
    ours = summary([measure_ours(v) for v in views])
    cv = summary([measure_opencv(v) for v in views])
    out: dict[str, Any] = {case: {**ours[case], 'opencv': cv[case]} for case in ours}
    out['views'] = len(views)
    out['convention_error_px'] = round(float(meta['convention']['error_px']), 4)
    # The time ratio from the two pipelines timed view by view in turn (five rounds): a busy
    # machine's drift then slows both alike, as it would not two passes one after the other.
    # Also each view's best of the five (what the machine does when nothing interrupts it).
    rounds = 5
    t_ours = np.zeros((rounds, len(views)))
    t_cv = np.zeros((rounds, len(views)))
    for r in range(rounds):
        for i, v in enumerate(views):
            t_ours[r, i] = measure_ours(v).seconds
            t_cv[r, i] = measure_opencv(v).seconds
    ms_ours, ms_cv = 1e3 * float(np.median(t_ours)), 1e3 * float(np.median(t_cv))
    out['time_ms_interleaved'] = {'ours': round(ms_ours, 2), 'opencv': round(ms_cv, 2)}
    out['time_ratio_vs_opencv'] = round(ms_ours / ms_cv, 2)
    best_ours = 1e3 * float(np.median(t_ours.min(axis=0)))
    best_cv = 1e3 * float(np.median(t_cv.min(axis=0)))
    out['time_ms_best_of_5'] = {'ours': round(best_ours, 2), 'opencv': round(best_cv, 2)}
    out['time_ratio_best_of_5'] = round(best_ours / best_cv, 2)
    return out


def run() -> dict[str, Any]:
    rng = np.random.default_rng(2024)
    cam = dynamic_camera()
    views = _views(rng)
    out: dict[str, Any] = {'views': N_VIEWS}
    comparison: dict[str, Any] = {}
    for name, fitter in FITTERS.items():
        c_err, n_err, times, fails = [], [], [], 0
        for img, _, c_true, n_true in views:
            t0 = time.perf_counter()
            m = measure_marker(img, cam, RADIUS, prior_normal=n_true, fitter=fitter)
            times.append(time.perf_counter() - t0)
            if m.status is not MeasurementStatus.OK or m.pose is None:
                fails += 1
                continue
            c_err.append(float(np.linalg.norm(m.pose.center - c_true)))
            n_err.append(math.degrees(angle_between(m.pose.normal, n_true)))
        comparison[name] = {
            'median_center_error_mm': round(1e3 * statistics.median(c_err), 4),
            'p90_center_error_mm': round(1e3 * float(np.percentile(c_err, 90)), 4),
            'median_normal_error_deg': round(statistics.median(n_err), 4),
            'p90_normal_error_deg': round(float(np.percentile(n_err, 90)), 4),
            'failures': fails,
            'median_ms_per_frame': round(1e3 * statistics.median(times), 3),
        }
    ours = comparison['weighted_ls']
    out['median_center_error_mm'] = ours['median_center_error_mm']
    out['median_normal_error_deg'] = ours['median_normal_error_deg']
    out['pose_ms_per_frame'] = ours['median_ms_per_frame']
    out['fitter_comparison'] = comparison
    best_cv_c = min(
        v['median_center_error_mm'] for k, v in comparison.items() if k != 'weighted_ls'
    )
    best_cv_n = min(
        v['median_normal_error_deg'] for k, v in comparison.items() if k != 'weighted_ls'
    )
    out['center_error_ratio_vs_best_opencv'] = round(ours['median_center_error_mm'] / best_cv_c, 3)
    out['normal_error_ratio_vs_best_opencv'] = round(
        ours['median_normal_error_deg'] / best_cv_n, 3
    )
    out['photoreal'] = photoreal()
    # A camera's renderer is made once (its rays and noise pools), as a simulated camera's is:
    # the per-frame cost is what a running camera pays (render() makes one for every call).
    # Each timed frame from another view: a still camera and scene would be the renderer's
    # kept frame with new noise (what a camera at rest costs), not a render.
    renderer = Renderer(cam)
    scene = Scene((Plate.disc([0.2, 0.1, 0.05], [0, -1, 0], RADIUS),))
    renderer.render(views[0][1], scene, rng=rng)
    t0 = time.perf_counter()
    for k in range(1, 11):
        renderer.render(views[k][1], scene, rng=rng)
    out['render_ms_per_frame'] = round(100 * (time.perf_counter() - t0), 1)
    t0 = time.perf_counter()
    for _ in range(10):
        renderer.render(views[10][1], scene, rng=rng)
    out['render_still_ms_per_frame'] = round(100 * (time.perf_counter() - t0), 1)
    return out
