"""Moved: the tracking metrics are :mod:`activesurv_studies.tracking` (this path keeps working)."""

from activesurv_studies.tracking import Snapshot, TrackRecorder, track_metrics

__all__ = ['Snapshot', 'TrackRecorder', 'track_metrics']
