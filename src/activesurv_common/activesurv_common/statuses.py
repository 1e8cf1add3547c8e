"""The statuses a camera's reading and a demand's estimate end in: the constants of
``activesurv_interfaces/MarkerObservation`` and ``TargetEstimate``, as enums every core (imaging,
fusion, evaluation) compares, and the names ``results.json`` writes."""

from __future__ import annotations

from enum import Enum


class ObservationStatus(Enum):
    """The status constants of ``activesurv_interfaces/MarkerObservation``."""

    OK = 0
    NOT_FOUND = 1
    REJECTED = 2
    NO_IMAGE = 3
    NO_CAMERA_POSE = 4
    POSE_FAILED = 5

    @property
    def located(self) -> bool:
        """Whether a frame was measured from a known camera pose (found or not)."""
        return self not in (ObservationStatus.NO_IMAGE, ObservationStatus.NO_CAMERA_POSE)


class DemandStatus(Enum):
    """The status constants of ``activesurv_interfaces/TargetEstimate``."""

    OK = 0
    NO_OBSERVATIONS = 1
    NO_CONSENSUS = 2
    PARTIAL = 3

    @property
    def label(self) -> str:
        """The name ``results.json`` gives it (``ok``, ``partial`` ...)."""
        return self.name.lower()

    @property
    def estimated(self) -> bool:
        """Whether the demand has a fused pose."""
        return self in (DemandStatus.OK, DemandStatus.PARTIAL)
