"""From an image to the marker pose in the camera frame: detect, undistort, fit, solve, choose.

This is the one place the imaging steps are chained, used by the imager node, the sensor-model
experiment and the benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_imaging.circle_pose import CirclePose, choose_pose, circle_poses
from activesurv_imaging.detect import (
    Detection,
    DetectionStatus,
    DetectorConfig,
    Fitter,
    detect_marker_detailed,
)
from activesurv_imaging.ellipse import Ellipse, fit_ellipse
from activesurv_imaging.errors import CirclePoseError, EllipseFitError
from activesurv_imaging.streak import MIN_STREAK, unswept

Array = NDArray[np.float64]


class MeasurementStatus(Enum):
    """Mirrors the status constants of ``activesurv_interfaces/MarkerObservation``."""

    OK = 0
    NOT_FOUND = 1
    REJECTED = 2
    POSE_FAILED = 5


@dataclass(frozen=True)
class MarkerMeasurement:
    """One camera's measurement of the marker.

    Attributes:
        status: OK or why not.
        reason: human-readable cause when not OK.
        ellipse: the fitted ellipse (undistorted pixels) when one was found.
        poses: both circle poses (camera optical frame) when solved.
        chosen: index of the pose chosen with the prior normal.
        margin: radians by which the chosen normal is closer to the prior than the other.
        swept: the ellipse as measured when a streak was taken out of it (``ellipse`` is
            then the marker at mid-exposure, unswept: :mod:`activesurv_imaging.streak`).
        blur_sigma: px, the isotropic blur its edges showed (lens, focus, pixel).
        visible: the fraction of its boundary measured (below 1: partly hidden, fitted to the
            arc that showed).
    """

    status: MeasurementStatus
    reason: str = ''
    ellipse: Ellipse | None = None
    poses: tuple[CirclePose, CirclePose] | None = None
    chosen: int = 0
    margin: float = 0.0
    swept: Ellipse | None = None
    blur_sigma: float = 0.0
    visible: float = 1.0

    @property
    def pose(self) -> CirclePose | None:
        return None if self.poses is None else self.poses[self.chosen]


def _one_pass(points: Array) -> Ellipse:
    """The direct fit without re-weighting (the detector's check of a blob)."""
    return fit_ellipse(points, iterations=0)


def _for_view(
    config: DetectorConfig | None, response: float, streak: Array | None
) -> DetectorConfig | None:
    """The detector's limits told the camera's response and the marker's streak (px)."""
    if response != 1.0:
        config = replace(config or DetectorConfig(), gamma=response)
    if streak is not None and np.all(np.isfinite(streak)) and np.hypot(*streak) >= MIN_STREAK:
        config = replace(
            config or DetectorConfig(),
            streak_length=float(np.hypot(*streak)),
            streak_angle=float(np.arctan2(streak[1], streak[0])),
        )
    return config


def measure_marker(
    image: ArrayLike,
    camera: CameraModel,
    radius: float,
    prior_normal: ArrayLike | None = None,
    fitter: Fitter | None = None,
    config: DetectorConfig | None = None,
    near: ArrayLike | None = None,
    detection: Detection | None = None,
    near_gate: float | None = None,
    gamma: float | None = None,
    streak: ArrayLike | None = None,
) -> MarkerMeasurement:
    """Measure the marker pose in one image.

    Args:
        image: 8-bit grey image from ``camera``.
        camera: its intrinsics (lens distortion is removed from the edge points before the fit).
        radius: marker radius, metres.
        prior_normal: expected marker normal in the camera frame (from the predicted pose),
            used to choose between the two solutions; ``None`` picks the normal that faces
            the camera more directly.
        fitter: ellipse fitter (default: the weighted fit of eq. 3-4).
        config: detector limits.
        near: (u, v) where the marker should be, to pick it among several in view (within
            ``near_gate`` px).
        detection: the marker's detection when already made (several markers: each in turn).
        gamma: the camera's response (``grey = 255 radiance^(1/gamma)``) the edges are
            measured through; None: the camera model's (``camera.gamma``, 1 unless its
            calibration says otherwise).
        streak: (du, dv) px the marker's image moved over the exposure (its predicted
            velocity times the exposure time, projected): the fitted ellipse is unswept
            (:func:`activesurv_imaging.streak.unswept`) before the pose is solved.

    Raises:
        ImagingError: if ``image`` is not an 8-bit image.
    """
    fit: Fitter = fit_ellipse if fitter is None else fitter
    s = None if streak is None else np.asarray(streak, dtype=np.float64).reshape(2)
    config = _for_view(config, camera.gamma if gamma is None else float(gamma), s)
    # With lens distortion the ellipse is fitted to the undistorted edges below: the
    # detector's own fit (of the distorted ones) only has to succeed, one unweighted pass.
    first: Fitter = _one_pass if camera.has_distortion and fitter is None else fit
    det = (
        detect_marker_detailed(image, config, first, near, near_gate)
        if detection is None
        else detection
    )
    if det.status is not DetectionStatus.OK or det.ellipse is None:
        status = (
            MeasurementStatus.NOT_FOUND
            if det.status is DetectionStatus.NOT_FOUND
            else MeasurementStatus.REJECTED
        )
        return MarkerMeasurement(status, det.reason)
    ellipse = det.ellipse
    if camera.has_distortion:
        try:
            ellipse = fit(camera.undistort_pixels(det.edge_points))
        except EllipseFitError as exc:
            return MarkerMeasurement(MeasurementStatus.REJECTED, f'undistorted fit failed: {exc}')
    swept = None
    if s is not None:
        swept, ellipse = ellipse, unswept(ellipse, s, det.blur_sigma)
        if ellipse is swept:
            swept = None
    try:
        poses = circle_poses(ellipse, camera.K, radius)
    except CirclePoseError as exc:
        return MarkerMeasurement(
            MeasurementStatus.POSE_FAILED,
            str(exc),
            ellipse,
            swept=swept,
            blur_sigma=det.blur_sigma,
            visible=det.visible,
        )
    if prior_normal is None:
        # Without a prior, prefer the pose seen more frontally (the smaller bearing).
        views = [float(p.normal @ (-p.center / np.linalg.norm(p.center))) for p in poses]
        chosen = int(np.argmax(views))
        margin = 0.0
    else:
        chosen, margin = choose_pose(poses, prior_normal)
    return MarkerMeasurement(
        MeasurementStatus.OK,
        '',
        ellipse,
        poses,
        chosen,
        margin,
        swept,
        det.blur_sigma,
        det.visible,
    )
