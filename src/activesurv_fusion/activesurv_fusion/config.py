"""What the fusion node is told (pure core): the typed half of a run description.

Bringup builds one from the experiments YAML; the graph turns it into the ``fusion`` node's
parameters (:meth:`FusionConfig.to_parameters`), lockstep hands its values to the cores
(:func:`activesurv_fusion.pose_fusion.resolve`), so both modes fuse alike.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from activesurv_fusion.errors import FusionError


@dataclass(frozen=True)
class FusionConfig:
    """Attributes:
    collect_timeout: s after a demand instant to wait for missing cameras.
    z_sigma: abstract-sensor half-width in standard deviations (3: 99.74 %).
    max_faulty: faulty cameras tolerated (k_f); -1: the largest k_f < k/2.
    """

    collect_timeout: float = 2.0
    z_sigma: float = 3.0
    max_faulty: int = -1

    def __post_init__(self) -> None:
        if not (math.isfinite(self.collect_timeout) and 0.0 < self.collect_timeout <= 600.0):
            raise FusionError(f'collect_timeout must be in (0, 600] s, got {self.collect_timeout}')
        if not (math.isfinite(self.z_sigma) and 0.0 < self.z_sigma <= 10.0):
            raise FusionError(f'z_sigma must be in (0, 10], got {self.z_sigma}')
        if self.max_faulty < -1:
            raise FusionError(f'max_faulty must be >= -1, got {self.max_faulty}')

    @property
    def faulty_limit(self) -> int | None:
        """``max_faulty`` as :func:`~activesurv_fusion.pose_fusion.resolve` takes it."""
        return None if self.max_faulty < 0 else self.max_faulty

    def to_parameters(self) -> dict[str, Any]:
        """The ``fusion`` node's parameters saying the same."""
        return asdict(self)
