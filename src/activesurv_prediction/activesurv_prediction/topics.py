"""Topic names of the predictor node (relative)."""

from __future__ import annotations

DEMAND_HORIZON = 'demand_horizon'
OVERHEAD_TRACK = 'overhead/track'
DIAGNOSTICS = '/diagnostics'


def image(camera_id: str) -> str:
    return f'{camera_id}/image_raw'


def camera_info(camera_id: str) -> str:
    return f'{camera_id}/camera_info'
