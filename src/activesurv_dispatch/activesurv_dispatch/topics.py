"""Topic names of the dispatcher node (relative; camera topics are prefixed by the camera id)."""

from __future__ import annotations

DEMAND_HORIZON = 'demand_horizon'
DISPATCH_PLAN = 'dispatch_plan'
CAPTURE_REQUEST = 'capture_request'
MARKERS = 'dispatch_markers'
DIAGNOSTICS = '/diagnostics'


def goal(camera_id: str) -> str:
    return f'{camera_id}/stage/goal'


def heartbeat(camera_id: str) -> str:
    return f'{camera_id}/imager/heartbeat'


def joint_states(camera_id: str) -> str:
    return f'{camera_id}/stage/joint_states'
