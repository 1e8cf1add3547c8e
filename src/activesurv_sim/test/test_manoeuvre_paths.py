"""The manoeuvring paths stay on Set A's region of the table and last through its demands."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_sim.paths import MANOEUVRES, manoeuvre_path


@pytest.mark.parametrize('kind', MANOEUVRES)
def test_manoeuvre_paths_stay_on_the_set_a_region(kind: str) -> None:
    path = manoeuvre_path(kind)
    assert path.duration > 12.0  # the ten demands (2-11 s after the start) see the manoeuvre
    assert np.all((path.xy[:, 0] >= 0.12) & (path.xy[:, 0] <= 0.38))
    assert np.all((path.xy[:, 1] >= 0.04) & (path.xy[:, 1] <= 0.1))
