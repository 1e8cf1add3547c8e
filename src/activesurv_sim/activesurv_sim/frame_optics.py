"""What the lens and the shutter do to one frame, as the renderer takes it (pure core).

Apart from :mod:`activesurv_sim.render` (which uses it and names it too) so that a rig's optics
(:mod:`activesurv_sim.optics`) and whatever reads a rig file do not load the renderer and its
compiled kernels: an orchestrator that only reads a rig started 0.3 s later so (numba).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class FrameOptics:
    """What the lens and the shutter do to one frame (:mod:`activesurv_sim.optics`).

    Attributes:
        defocus_sigma: the depth of field's blur (px, per axis), in quadrature with the lens's
            own ``SensorNoise.blur_sigma``.
        streak: the marker's image displacement over the exposure (px, u and v): the frame is
            smeared along it (motion blur).
        gain: grey levels relative to the renderer's (exposure time / reference).
        gamma: the response, ``grey = 255 (radiance / full scale)^(1 / gamma)``.
    """

    defocus_sigma: float = 0.0
    streak: tuple[float, float] = (0.0, 0.0)
    gain: float = 1.0
    gamma: float = 1.0

    def blur(self, base: float) -> float:
        return math.hypot(base, self.defocus_sigma)

    @property
    def streak_length(self) -> float:
        return math.hypot(*self.streak)


IDEAL_OPTICS = FrameOptics()
