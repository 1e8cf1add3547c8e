"""The predictor's session core and its typed config (the node and lockstep drive both)."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_prediction.errors import PredictionError
from activesurv_prediction.predictor_node import PARAMS
from activesurv_prediction.session import PredictionSession, PredictorConfig
from activesurv_prediction.tracker import TrackState


def test_the_config_is_the_nodes_parameters_and_back() -> None:
    config = PredictorConfig(demand_times=(2.0, 3.0), horizon=3, side_offset=(0.0, -0.02, -0.03))
    params = config.to_parameters()
    declared = {p.name for p in PARAMS}
    assert set(params) <= declared, set(params) - declared
    assert PredictorConfig.from_parameters(params) == config
    # Unset values take the defaults; bad ones are refused with the parameter's name.
    assert PredictorConfig.from_parameters({}) == PredictorConfig()
    with pytest.raises(PredictionError, match='side_marker_offset'):
        PredictorConfig.from_parameters({'side_marker_offset': [0.0, 1.0]})
    with pytest.raises(PredictionError, match='several objects'):
        PredictorConfig(objects_at_once=2)  # needs continuous demands


def test_a_session_confirms_a_track_and_predicts_the_schedule() -> None:
    session = PredictionSession(PredictorConfig(demand_times=(3.0, 4.0), confirm_fixes=5))
    out = None
    for k in range(12):
        t = 0.1 * k
        out = session.on_fix(t, [0.1 + 0.02 * t, 0.1]) or out
    assert out is not None
    assert out.state is TrackState.CONFIRMED
    assert [d.index for d in out.demands] == [0, 1]
    assert out.demands[0].position[0] == pytest.approx(0.1 + 0.02 * 3.0, abs=2e-3)
    assert len(out.tracks) == 1
    assert np.allclose(out.tracks[0].velocity, [0.02, 0.0], atol=2e-3)
    assert any('TENTATIVE -> CONFIRMED' in e for e in out.events) or session.state() is (
        TrackState.CONFIRMED
    )
    lost = session.tick(10.0)  # not seen for far longer than lost_timeout
    assert lost is not None
    assert lost.state is TrackState.LOST
    with pytest.raises(PredictionError):
        session.on_fixes(1.0, [[0.1, 0.1]])  # one object at a time
