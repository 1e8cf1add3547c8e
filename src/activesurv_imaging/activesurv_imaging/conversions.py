"""Conversions between the imaging cores' values and messages (marker observations).

Stamps, camera info, images, joint states and mount parameters are shared by every node:
:mod:`activesurv_common.ros.conversions`.
"""

from __future__ import annotations

import math

import numpy as np

from activesurv_common.ros.conversions import pose_from_transform, sec_to_time
from activesurv_imaging.observation import Observation
from activesurv_interfaces.msg import MarkerObservation

NAN3 = (math.nan, math.nan, math.nan)


# -- observations --------------------------------------------------------------------------
def observation_to_msg(obs: Observation, frame_id: str = 'world') -> MarkerObservation:
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
    return msg
