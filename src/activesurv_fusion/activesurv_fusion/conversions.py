"""Conversions between activesurv messages and the fusion core's values."""

from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped

from activesurv_common.statuses import DemandStatus
from activesurv_fusion.collector import Answer, DemandResult, camera_answer

__all__ = [
    'observation_to_answer',
    'request_fields',
    'result_to_estimate',
    'result_to_pose',
    'sec_to_time',
    'time_to_sec',
]
from activesurv_common.geometry import normal_to_rotation_covariance, quaternion_from_normal
from activesurv_common.ros.conversions import sec_to_time, time_to_sec
from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, TargetEstimate


def request_fields(
    msg: CaptureRequest,
) -> tuple[int, float, tuple[str, ...], tuple[float, float, float]]:
    """(demand index, demand time, assigned cameras, prior normal) of a capture request."""
    n = msg.predicted_normal
    return (
        int(msg.demand_index),
        time_to_sec(msg.demand_instant),
        tuple(str(c) for c in msg.camera_ids),
        (float(n.x), float(n.y), float(n.z)),
    )


def observation_to_answer(msg: MarkerObservation) -> Answer:
    """A camera's answer (:func:`~activesurv_fusion.collector.camera_answer`)."""
    p, n = msg.position, msg.normal
    return camera_answer(
        msg.camera_id,
        msg.status == MarkerObservation.STATUS_OK,
        (p.x, p.y, p.z),
        (n.x, n.y, n.z),
        msg.covariance,
        msg.reason or f'status {msg.status}',
    )


def result_to_estimate(
    result: DemandResult, frame_id: str, now: float = math.nan
) -> TargetEstimate:
    """``now``: fusion's clock as it publishes (``published``, the latency budget)."""
    msg = TargetEstimate()
    msg.published = float(now - result.demand_time)
    msg.header.stamp = sec_to_time(result.demand_time)
    msg.header.frame_id = frame_id
    msg.demand_index = result.index
    msg.status = int(result.status.value)
    msg.reason = result.reason
    msg.cameras_missing = list(result.cameras_missing)
    fused = result.fused
    if fused is None:
        msg.position.x = msg.position.y = msg.position.z = float('nan')
        msg.normal.x = msg.normal.y = msg.normal.z = float('nan')
        msg.covariance = [float('nan')] * 36
        msg.region_lower = [float('nan')] * 6
        msg.region_upper = [float('nan')] * 6
        return msg
    msg.position.x, msg.position.y, msg.position.z = (float(v) for v in fused.position)
    msg.normal.x, msg.normal.y, msg.normal.z = (float(v) for v in fused.normal)
    msg.covariance = [float(v) for v in fused.covariance.reshape(-1)]
    msg.region_lower = [float(v) for v in fused.lower]
    msg.region_upper = [float(v) for v in fused.upper]
    msg.cameras_used = list(fused.cameras_used)
    msg.cameras_faulty = list(fused.cameras_faulty)
    msg.fused_visibility = result.fused_visibility
    return msg


def result_to_pose(result: DemandResult, frame_id: str) -> PoseWithCovarianceStamped | None:
    """The fused pose for standard ROS consumers (None when the demand has no estimate).

    The covariance is over (x, y, z, rot_x, rot_y, rot_z); the rotation block follows from the
    normal covariance, and rotation about the normal (not observable from a circle) gets pi^2.
    """
    fused = result.fused
    if fused is None or result.status not in (DemandStatus.OK, DemandStatus.PARTIAL):
        return None
    msg = PoseWithCovarianceStamped()
    msg.header.stamp = sec_to_time(result.demand_time)
    msg.header.frame_id = frame_id
    pose = msg.pose.pose
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in fused.position)
    q = quaternion_from_normal(fused.normal)
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
        float(v) for v in q
    )
    cov = np.zeros((6, 6))
    cov[:3, :3] = fused.covariance[:3, :3]
    cov[3:, 3:] = normal_to_rotation_covariance(fused.normal, fused.covariance[3:, 3:])
    msg.pose.covariance = [float(v) for v in cov.reshape(-1)]
    return msg
