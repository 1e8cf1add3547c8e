"""How a camera's exposures are timed and where its frames come from (one vocabulary for the
hardware file, the imager and the orchestrator; both are ``StrEnum``: they compare equal to
the strings in YAML files and ROS parameters)."""

from __future__ import annotations

from enum import StrEnum


class Trigger(StrEnum):
    """How a camera's exposures are timed."""

    HARDWARE = 'hardware'  # a trigger line exposes at the instant
    SOFTWARE = 'software'  # our capture request (or the driver's Trigger service) exposes
    FREE = 'free'  # free-running: the frame nearest the instant is taken


class SourceKind(StrEnum):
    """Where a camera's frames come from."""

    TOPIC = 'topic'  # a ROS 2 driver publishes the frames
    DEVICE = 'device'  # our camera node opens the device (OpenCV VideoCapture)
