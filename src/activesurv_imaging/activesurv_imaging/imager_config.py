"""How one imager measures (:class:`ImagerConfig`): a module of its own, light to import (no
OpenCV, no numba), so that an orchestrator that only writes an imager's parameters does not
load the imaging kernels before it starts a graph."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from activesurv_common.occlusion import Obstacle
from activesurv_common.trigger import Trigger
from activesurv_imaging.errors import ImagingError

TRIGGERS = ('hardware', 'software', 'free')


@dataclass(frozen=True)
class ImagerConfig:
    """How one imager measures.

    Attributes:
        camera_id: the camera it serves.
        marker_radius: radius of the side marker (m).
        frame_tolerance: largest |frame stamp - demand instant| accepted (s).
        frame_timeout: s after the demand instant before it answers with a failure.
        joint_hold: s a stage state may be held beyond its stamp.
        inject_bias_x: fault injection: m added to the world x of every estimate.
        inject_noise: fault injection: extra position noise (m, std).
        inject_flip: fault injection: take the wrong one of the two circle poses.
        exact_state: wait (up to ``joint_hold`` past the frame) for a stage state stamped at
            the frame's instant itself, as stages that latch their position on the trigger
            publish (the simulated ones do): a replay then measures with the same state.
        obstacles: the cell's solids: a marker not found (or rejected) behind one is reported
            as occluded.
        several_objects: several objects at once: of the markers in view, measure the one
            nearest the demand's predicted position (15 mm at most), never another's.
        exposure_time: s the shutter is open: the streak a moving marker leaves over it is
            taken out of its ellipse (:mod:`activesurv_imaging.streak`); 0: the camera
            model's (its calibration YAML's), if any.
        gamma: the camera's response the frames are linearised with (its calibration's:
            commissioning estimates it); 0: the camera model's.
        pointing_std: rad the calibration leaves unknown of where the camera points, added to
            every reading's covariance (:func:`with_pointing`; 0.1 mrad: what commissioned
            simulated rigs show, see docs/design-choices.md).
    """

    camera_id: str
    marker_radius: float = 0.0125
    frame_tolerance: float = 0.005
    frame_timeout: float = 1.0
    joint_hold: float = 0.2
    inject_bias_x: float = 0.0
    inject_noise: float = 0.0
    inject_flip: bool = False
    exact_state: bool = False
    trigger: str = 'hardware'
    frame_rate: float = 0.0
    exposure_delay: float = 0.0
    exposure_time: float = 0.0
    gamma: float = 0.0
    motion_correction: bool = True
    free_reach: float = 3.25
    velocity_std: float = 0.002
    pointing_std: float = 1e-4
    obstacles: tuple[Obstacle, ...] = ()
    several_objects: bool = False

    def __post_init__(self) -> None:
        if self.trigger not in TRIGGERS:
            raise ImagingError(f'trigger must be one of {TRIGGERS}, got {self.trigger!r}')
        if self.trigger == Trigger.FREE and not (
            math.isfinite(self.frame_rate) and self.frame_rate > 0.0
        ):
            raise ImagingError(f'free-running needs frame_rate > 0, not {self.frame_rate}')
        if not (self.gamma == 0.0 or (math.isfinite(self.gamma) and 0.2 <= self.gamma <= 5.0)):
            raise ImagingError(
                f"gamma must be 0 (the camera model's) or in [0.2, 5], got {self.gamma}"
            )
        if not (math.isfinite(self.exposure_time) and 0.0 <= self.exposure_time <= 1.0):
            raise ImagingError(f'exposure_time must be in [0, 1] s, got {self.exposure_time}')
        if not (math.isfinite(self.exposure_delay) and self.exposure_delay >= 0.0):
            raise ImagingError(f'exposure_delay must be >= 0 s, got {self.exposure_delay}')
        if not (math.isfinite(self.free_reach) and self.free_reach >= 0.5):
            raise ImagingError(f'free_reach must be >= 0.5 periods, got {self.free_reach}')
        if not (math.isfinite(self.velocity_std) and self.velocity_std >= 0.0):
            raise ImagingError(f'velocity_std must be >= 0 m/s, got {self.velocity_std}')
        if not (math.isfinite(self.pointing_std) and 0.0 <= self.pointing_std <= 0.1):
            raise ImagingError(f'pointing_std must be in [0, 0.1] rad, got {self.pointing_std}')

    def to_parameters(self) -> dict[str, Any]:
        """The ``imager`` node's parameters saying the same (``obstacles`` excepted: the node
        reads them from ``obstacles_file``)."""
        out: dict[str, Any] = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in ('obstacles', 'exact_state')
        }
        out['exact_states'] = self.exact_state
        return out

    @property
    def tolerance(self) -> float:
        """Largest |exposure - demand instant| accepted: half a period when free-running."""
        if self.trigger == Trigger.FREE:
            # The nearest frame is within half a period (plus the stamps' jitter); when it was
            # dropped, the nearest that came is still taken (and moved to the instant).
            return self.free_reach / self.frame_rate
        return self.frame_tolerance
