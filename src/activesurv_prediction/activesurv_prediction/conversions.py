"""Conversions between the prediction cores and messages."""

from __future__ import annotations

from activesurv_common.geometry import quaternion_from_normal
from activesurv_common.ros.conversions import sec_to_time
from activesurv_interfaces.msg import DemandHorizon, DemandPoint, ObjectTrack, ObjectTracks
from activesurv_prediction.demands import DemandPrediction
from activesurv_prediction.tracker import MotionSummary, TrackEstimate, TrackState


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
        q = quaternion_from_normal(p.normal)
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
            float(v) for v in q
        )
        d.pose.covariance = [float(v) for v in p.covariance.reshape(-1)]
        d.normal.x, d.normal.y, d.normal.z = (float(v) for v in p.normal)
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
