"""Conversions between the prediction cores and messages."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from visualization_msgs.msg import Marker, MarkerArray

from activesurv_common.geometry import quaternion_from_normal
from activesurv_common.ros.conversions import sec_to_time
from activesurv_interfaces.msg import DemandHorizon, DemandPoint, ObjectTrack, ObjectTracks
from activesurv_prediction.demands import DemandPrediction
from activesurv_prediction.tracker import MotionSummary, TrackEstimate, TrackState


@lru_cache(maxsize=16)
def _orientation(normal: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """:func:`quaternion_from_normal` of a demand's normal: a horizon's demands share their
    target's one normal, and a horizon goes out at every overhead fix (0.2-0.4 ms of its
    construction was these few rotations)."""
    x, y, z, w = (float(v) for v in quaternion_from_normal(normal))
    return x, y, z, w


def horizon_to_msg(
    predictions: list[DemandPrediction],
    state: TrackState,
    stamp: float,
    frame_id: str,
    motion: MotionSummary | None = None,
) -> DemandHorizon:
    msg = DemandHorizon()
    if motion is not None:
        msg.mode_names = list(motion.mode_names)
        msg.mode_probabilities = [float(v) for v in motion.probabilities]
        msg.motion = motion.regime
        msg.manoeuvre = bool(motion.manoeuvre)
        msg.manoeuvre_count = int(motion.manoeuvre_count)
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    msg.track_state = int(state.value)
    for p in predictions:
        d = DemandPoint(index=int(p.index), object_id=int(p.object_id))
        d.demand_instant = sec_to_time(p.instant)
        pose = d.pose.pose
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in p.position)
        normal = (float(p.normal[0]), float(p.normal[1]), float(p.normal[2]))
        o = pose.orientation
        o.x, o.y, o.z, o.w = _orientation(normal)
        d.pose.covariance = np.array(p.covariance, dtype=np.float64).reshape(36)
        d.normal.x, d.normal.y, d.normal.z = normal
        d.velocity.x, d.velocity.y, d.velocity.z = (float(v) for v in p.velocity)
        msg.demands.append(d)
    return msg


def tracks_to_msg(
    tracks: list[TrackEstimate], stamp: float, frame_id: str, top_height: float
) -> ObjectTracks:
    """The overhead tracks at ``stamp`` (positions at the top marker's height)."""
    msg = ObjectTracks()
    msg.header.stamp = sec_to_time(stamp)
    msg.header.frame_id = frame_id
    for t in tracks:
        m = ObjectTrack()
        m.id = int(t.object_id)
        m.state = ObjectTrack.STATE_CONFIRMED if t.confirmed else ObjectTrack.STATE_TENTATIVE
        m.position.x, m.position.y, m.position.z = float(t.xy[0]), float(t.xy[1]), top_height
        m.velocity.x, m.velocity.y = float(t.velocity[0]), float(t.velocity[1])
        m.covariance_xy = [float(v) for v in t.covariance.reshape(4)]
        msg.tracks.append(m)
    return msg


def track_markers(
    tracks: list[TrackEstimate], stamp: float, frame_id: str, top_height: float
) -> MarkerArray:
    """Every overhead track for viewers: a sphere at its top marker (green once confirmed,
    amber while tentative) and its object id above it."""
    arr = MarkerArray()
    arr.markers.append(Marker(action=Marker.DELETEALL))
    t = sec_to_time(stamp)
    for i, k in enumerate(tracks):
        for kind in (Marker.SPHERE, Marker.TEXT_VIEW_FACING):
            m = Marker(ns='tracks', id=2 * i + int(kind == Marker.TEXT_VIEW_FACING), type=kind)
            m.action = Marker.ADD
            m.header.frame_id, m.header.stamp = frame_id, t
            m.pose.position.x, m.pose.position.y = float(k.xy[0]), float(k.xy[1])
            m.pose.position.z = top_height + (0.03 if kind == Marker.TEXT_VIEW_FACING else 0.0)
            m.pose.orientation.w = 1.0
            m.scale.x = m.scale.y = m.scale.z = 0.02
            m.color.r, m.color.g, m.color.b = (0.2, 0.8, 0.2) if k.confirmed else (1.0, 0.7, 0.1)
            m.color.a = 0.9
            if kind == Marker.TEXT_VIEW_FACING:
                m.text = f'object {k.object_id}' if k.object_id else 'tentative'
            arr.markers.append(m)
    return arr
