"""Manoeuvre detection from the IMM's mode probabilities (pure core).

The object's motion is in one of three regimes: ``stopped`` (the stationary mode dominates),
``moving`` (constant velocity) or ``accelerating`` (constant acceleration: turning, speeding up
or slowing down). A regime holds until another mode's probability exceeds ``enter`` (hysteresis:
probabilities hovering near one half do not flicker). Every change of regime, and every restart
of the filter, is a *manoeuvre*: predictions made before it are stale, and the dispatcher
replans as when a prediction leaves its box.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from activesurv_prediction.errors import PredictionError

REGIMES = ('stopped', 'moving', 'accelerating')


class ManoeuvreDetector:
    """Regime of the object's motion and the manoeuvres between regimes.

    Args:
        enter: probability above which a mode's regime is entered (0.5 .. 1).
    """

    def __init__(self, enter: float = 0.8) -> None:
        if not (math.isfinite(enter) and 0.5 <= enter < 1.0):
            raise PredictionError(f'manoeuvre threshold must be in [0.5, 1), got {enter}')
        self.enter = enter
        self.regime = ''
        self.count = 0

    def reset(self) -> None:
        """A new track: no regime yet, no manoeuvre so far."""
        self.regime = ''
        self.count = 0

    def update(self, probabilities: ArrayLike, restarted: bool = False) -> bool:
        """Feed the mode probabilities (stationary, CV, CA) after a fix; True on a manoeuvre.

        A single-mode predictor (one probability) only manoeuvres when it restarts.
        """
        mu = np.asarray(probabilities, dtype=np.float64).reshape(-1)
        changed = False
        if mu.shape == (3,) and np.all(np.isfinite(mu)):
            best = int(np.argmax(mu))
            if REGIMES[best] != self.regime and mu[best] > self.enter:
                changed = self.regime != ''
                self.regime = REGIMES[best]
        if changed or restarted:
            self.count += 1
        return changed or restarted
