"""Conversions between the imaging cores' values and messages (marker observations).

Stamps, camera info, images, joint states and mount parameters are shared by every node:
:mod:`activesurv_common.ros.conversions`.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import ImageMarker

from activesurv_common.camera_model import CameraModel, intrinsics_discrepancy
from activesurv_common.ros.conversions import (
    image_to_gray,
    model_from_camera_info,
    pose_from_transform,
    sec_to_time,
    time_to_sec,
)
from activesurv_imaging.annotations import Shape
from activesurv_imaging.errors import VisionErrors
from activesurv_imaging.observation import Observation
from activesurv_interfaces.msg import MarkerObservation

NAN3 = (math.nan, math.nan, math.nan)
PNG_MONO = 'mono8; png compressed mono8'  # image_transport's compressed format string


def demand_frame_msg(image: Image, frame_id: str) -> CompressedImage:
    """The frame an imager measured, as recorded: PNG, stamped as the camera stamped it (an
    observation's stamp is its exposure instant, this stamp minus ``exposure_delay``)."""
    return frame_to_compressed(image_to_gray(image), time_to_sec(image.header.stamp), frame_id)


def info_disagreement(
    commissioned: CameraModel, msg: CameraInfo, camera_id: str, tolerance: float
) -> str | None:
    """Why a driver's camera_info is not to be trusted beside the commissioned intrinsics (it
    disagrees beyond ``tolerance`` px), or None."""
    try:
        driver = model_from_camera_info(msg, camera_id)
    except VisionErrors:
        return None
    off = intrinsics_discrepancy(commissioned, driver)
    if off <= tolerance:
        return None
    return (
        f"the driver's camera_info disagrees with the commissioned intrinsics by {off:.1f} px "
        f'(tolerance {tolerance:g} px): the commissioned ones are used; point the driver at '
        'them (its camera_info_url)'
    )


def frame_to_compressed(gray: np.ndarray, stamp: float, frame_id: str) -> CompressedImage:
    """A grey frame as a lossless PNG ``CompressedImage`` (what hardware runs record)."""
    ok, data = cv2.imencode('.png', np.ascontiguousarray(gray, dtype=np.uint8))
    if not ok:
        raise ValueError('PNG encoding failed')
    msg = CompressedImage()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.format = PNG_MONO
    msg.data = data.tobytes()
    return msg


# -- observations --------------------------------------------------------------------------
def observation_to_msg(
    obs: Observation, frame_id: str = 'world', now: float = math.nan
) -> MarkerObservation:
    """``now``: the imager's clock as it publishes (``published``, the latency budget)."""
    msg = MarkerObservation()
    msg.header.stamp = sec_to_time(obs.stamp)
    msg.header.frame_id = frame_id
    msg.camera_id = obs.camera_id
    msg.demand_index = int(obs.demand_index)
    msg.status = int(obs.status.value)
    msg.reason = obs.reason
    pos = obs.position if obs.position is not None else NAN3
    nrm = obs.normal if obs.normal is not None else NAN3
    msg.position.x, msg.position.y, msg.position.z = (float(v) for v in pos)
    msg.normal.x, msg.normal.y, msg.normal.z = (float(v) for v in nrm)
    cov = obs.covariance if obs.covariance is not None else np.full((6, 6), math.nan)
    msg.covariance = [float(v) for v in np.asarray(cov).reshape(-1)]
    if obs.ellipse is not None:
        e = obs.ellipse
        msg.ellipse.center_x, msg.ellipse.center_y = (float(v) for v in e.center)
        msg.ellipse.semi_major, msg.ellipse.semi_minor = (float(v) for v in e.semi_axes)
        msg.ellipse.angle = float(e.angle)
    msg.chosen_solution = int(obs.chosen)
    msg.solution_margin = float(obs.margin)
    msg.distance = float(obs.distance)
    msg.bearing = float(obs.bearing)
    if obs.camera_pose is not None:
        msg.camera_pose = pose_from_transform(obs.camera_pose)
    msg.frame_offset = float(obs.frame_offset)
    msg.compute_time = float(obs.compute_time)
    msg.frame_received = float(obs.frame_received)
    msg.published = float(now - obs.demand_time)  # NaN where either is unknown
    if obs.motion_correction is not None:
        c = msg.motion_correction
        c.x, c.y, c.z = (float(v) for v in obs.motion_correction)
    return msg


# -- annotations ---------------------------------------------------------------------------
GREEN = ColorRGBA(r=0.1, g=0.9, b=0.2, a=1.0)
YELLOW = ColorRGBA(r=1.0, g=0.85, b=0.1, a=1.0)
RED = ColorRGBA(r=1.0, g=0.15, b=0.1, a=1.0)
_TYPES = {
    'ellipse': ImageMarker.LINE_STRIP,
    'centre': ImageMarker.CIRCLE,
    'normal': ImageMarker.LINE_LIST,
    'status': ImageMarker.CIRCLE,
}
_COLOURS = {'ellipse': GREEN, 'centre': GREEN, 'normal': YELLOW, 'status': RED}


def annotation_markers(
    shapes: list[Shape], stamp: float, frame_id: str, demand_index: int
) -> list[ImageMarker]:
    """One ImageMarker per shape, stamped like the image. ``ns`` names the demand and, for a
    failure, carries its status and reason (ImageMarker has no text field); markers live 5 s.
    """
    out = []
    for i, shape in enumerate(shapes):
        m = ImageMarker()
        m.header.stamp = sec_to_time(stamp)
        m.header.frame_id = frame_id
        m.ns = f'demand {demand_index}' + (f': {shape.label}' if shape.label else '')
        m.id = i
        m.type = _TYPES[shape.kind]
        m.action = ImageMarker.ADD
        m.outline_color = _COLOURS[shape.kind]
        m.scale = float(shape.size) if shape.size else 2.0
        m.lifetime = Duration(sec=5)
        if shape.kind in ('centre', 'status'):
            m.position = Point(x=shape.points[0][0], y=shape.points[0][1], z=0.0)
            m.filled = 0
        else:
            m.points = [Point(x=x, y=y, z=0.0) for x, y in shape.points]
        out.append(m)
    return out
