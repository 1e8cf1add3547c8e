"""Topic names used by the fusion node (relative: they follow the node's namespace)."""

from __future__ import annotations

CAPTURE_REQUEST = 'capture_request'
MARKER_OBSERVATIONS = 'marker_observations'
TARGET_ESTIMATE = 'target_estimate'
TARGET_POSE = 'target_pose'
DIAGNOSTICS = '/diagnostics'
