"""One demand's record from the messages a bag holds for it (experiments and sessions)."""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum
from typing import Any, TypeVar

import numpy as np

from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.occlusion import Obstacle, obstacles_from_list, sight_blocked
from activesurv_common.sensor_model import SensorModel
from activesurv_common.statuses import DemandStatus, ObservationStatus
from activesurv_evaluation.results import DemandRecord, visibility_from_transforms
from activesurv_evaluation.timing import published
from activesurv_recording.run_record import RunRecord

S = TypeVar('S', bound=Enum)

TRUTH_TOLERANCE = 1e-3
"""s past the newest truth sample an instant may lie and still take it (stamps' rounding)."""


def _status(kind: type[S], value: Any) -> S | None:
    """A recorded status constant as its enum (None for a value the enum does not know)."""
    try:
        return kind(int(value))
    except ValueError:
        return None


def run_obstacles(record: RunRecord) -> tuple[Obstacle, ...] | None:
    """The simulated cell's obstacles of a run (None for a hardware run: nothing there knows
    where the lines of sight really went)."""
    if record.hardware is not None:
        return None
    return obstacles_from_list(list(record.obstacles))


# What every evaluator reads: the truth, the overhead tracks, the horizon, and each demand's
# request, observations and estimate.
DEMAND_TOPICS = frozenset(
    {
        '/object_state',
        '/object_tracks',
        '/demand_horizon',
        '/capture_request',
        '/marker_observations',
        '/target_estimate',
    }
)


class DemandMessages:
    """Each demand's capture request, observations (with their receive times) and estimate
    (with its bag time, ns), gathered from a bag message by message."""

    def __init__(self) -> None:
        self.requests: dict[int, Any] = {}
        self.observations: dict[int, list[tuple[Any, float]]] = {}
        self.estimates: dict[int, tuple[Any, int]] = {}

    def hear_demand(self, m: Any) -> bool:
        """Note a request, observation or estimate; False for any other topic."""
        if m.topic == '/capture_request':
            self.requests.setdefault(int(m.msg.demand_index), m.msg)
        elif m.topic == '/marker_observations':
            self.observations.setdefault(int(m.msg.demand_index), []).append(
                (m.msg, m.t_ns * 1e-9)
            )
        elif m.topic == '/target_estimate':
            self.estimates.setdefault(int(m.msg.demand_index), (m.msg, m.t_ns))
        else:
            return False
        return True


def msg_stamp(msg: Any) -> float:
    """A stamped message's header time (s)."""
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def msg_vector(v: Any) -> np.ndarray:
    """A geometry_msgs Point or Vector3 as a (3,) array."""
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def demand_record(
    j: int,
    tj: float,
    truth: np.ndarray,
    req: Any,
    observations: Sequence[Any],
    est: tuple[Any, int] | None,
    model: SensorModel,
    obstacles: Sequence[Obstacle] | None = None,
    radius: float = 0.0125,
) -> DemandRecord:
    """The record of demand ``j`` at ``tj`` from its messages in a bag.

    Args:
        truth: side marker position and normal at ``tj`` (6,).
        req: its capture request, or None.
        observations: its marker observations.
        est: its target estimate and the bag time it was recorded at (ns), or None.
        model: the sensor model, for the visibility of the cameras that imaged the marker.
        obstacles: the simulated cell's obstacles (None: unknown, a hardware run): an
            assigned camera whose line of sight from where its observation puts it (its
            stage state at the frame) to the true marker passes through one is ``occluded``.
        radius: the marker's radius (a line of sight that close to an obstacle cuts it).
    """
    rec = DemandRecord(j, tj, truth[:3], truth[3:])
    if req is not None:
        rec.assigned = [str(c) for c in req.camera_ids]
    seen = []
    for o in observations:
        status = _status(ObservationStatus, o.status)
        # Frame stamp minus demand instant (free-running cameras; 0 for triggered ones).
        if status is not ObservationStatus.NO_IMAGE:  # no frame, no offset
            rec.frame_offsets[str(o.camera_id)] = float(getattr(o, 'frame_offset', 0.0))
        if status is ObservationStatus.OK:
            p, q = o.camera_pose.position, o.camera_pose.orientation
            seen.append(
                Transform.from_rt(matrix_from_quaternion([q.x, q.y, q.z, q.w]), [p.x, p.y, p.z])
            )
    known = bool(np.all(np.isfinite(truth)))  # no truth at the instant: nothing to see it by
    rec.visibility = (
        visibility_from_transforms(model, seen, truth[:3], truth[3:]) if seen and known else 0.0
    )
    rec.occluded = None if obstacles is None else []
    if obstacles and rec.occluded is not None and known:
        for o in observations:
            if (
                str(o.camera_id) not in rec.assigned
                or not ObservationStatus(int(o.status)).located
            ):
                continue  # no frame or no stage state: where it looked from is unknown
            p = o.camera_pose.position
            if sight_blocked([p.x, p.y, p.z], truth[:3], obstacles, radius, truth[3:])[0]:
                rec.occluded.append(str(o.camera_id))
    if est is None:
        rec.status = 'not_captured' if req is None else 'no_answer'
        rec.reason = (
            'the demand passed with no capture request'
            if req is None
            else 'no target_estimate was recorded for it'
        )
        return rec
    e, t_ns = est
    outcome = _status(DemandStatus, e.status)
    rec.status = outcome.label if outcome is not None else f'status_{e.status}'
    rec.reason = str(e.reason)
    rec.cameras = [str(c) for c in e.cameras_used]
    rec.faulty = [str(c) for c in e.cameras_faulty]
    rec.missing = [str(c) for c in e.cameras_missing]
    # As fusion published it (its fine clock); older bags: as the recorder heard it.
    told = published(e)
    rec.latency = told if told is not None else t_ns * 1e-9 - tj
    if outcome is not None and outcome.estimated and np.all(np.isfinite(msg_vector(e.position))):
        rec.estimated_position = msg_vector(e.position)
        rec.estimated_normal = msg_vector(e.normal)
    return rec
