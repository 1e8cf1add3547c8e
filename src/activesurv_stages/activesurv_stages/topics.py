"""Topic names of the stage nodes (relative; camera topics are prefixed by the camera id)."""

from __future__ import annotations

OBJECT_STATE = 'object_state'
CLOCK = '/clock'
DIAGNOSTICS = '/diagnostics'


def goal(camera_id: str) -> str:
    return f'{camera_id}/stage/goal'


def joint_states(camera_id: str) -> str:
    return f'{camera_id}/stage/joint_states'
