"""Topic names of the imaging nodes (relative; camera topics are prefixed by the camera id)."""

from __future__ import annotations

OBJECT_STATE = 'object_state'
CAPTURE_REQUEST = 'capture_request'
MARKER_OBSERVATIONS = 'marker_observations'
DIAGNOSTICS = '/diagnostics'


def image(camera_id: str) -> str:
    return f'{camera_id}/image_raw'


def camera_info(camera_id: str) -> str:
    return f'{camera_id}/camera_info'


def heartbeat(camera_id: str) -> str:
    """The imager's liveness beat (std_msgs/Header, frame_id = camera id, 10 Hz)."""
    return f'{camera_id}/imager/heartbeat'


def joint_states(camera_id: str) -> str:
    return f'{camera_id}/stage/joint_states'
