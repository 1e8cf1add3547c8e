"""A demand's record from its messages (no ROS): what is written when the truth has a gap."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from activesurv_common.sensor_model import SensorModel
from activesurv_evaluation.records import demand_record
from activesurv_evaluation.results import summary


def _v(x: float, y: float, z: float) -> SimpleNamespace:
    return SimpleNamespace(x=x, y=y, z=z)


def _estimate() -> SimpleNamespace:
    return SimpleNamespace(
        status=0,
        reason='',
        cameras_used=['cam1', 'cam2'],
        cameras_faulty=[],
        cameras_missing=[],
        position=_v(0.1, 0.2, 0.08),
        normal=_v(0.0, -1.0, 0.0),
    )


def test_a_demand_without_truth_near_it_is_kept_with_null_errors() -> None:
    model = SensorModel.load()
    req = SimpleNamespace(camera_ids=['cam1', 'cam2'])
    truth = np.array([0.1, 0.2001, 0.08, 0.0, -1.0, 0.0])
    known = demand_record(0, 1.5, truth, req, [], (_estimate(), int(1.55e9)), model)
    gap = demand_record(1, 2.5, np.full(6, np.nan), req, [], (_estimate(), int(2.56e9)), model)
    assert known.position_error is not None
    assert abs(known.position_error - 1e-4) < 1e-9
    assert gap.position_error is None
    assert gap.orientation_error is None
    row = gap.to_json()
    assert row['true_position'] is None
    assert row['true_normal'] is None
    assert row['estimated_position'] == [0.1, 0.2, 0.08]
    assert row['status'] == known.status
    assert abs(row['latency'] - 0.06) < 1e-9
    doc = {'demands': [known.to_json(), row]}
    text = json.dumps(doc, allow_nan=False)  # strict JSON: no NaN anywhere
    s = summary(json.loads(text))
    assert s['estimates'] == 2.0
    assert abs(s['median_position_error'] - 1e-4) < 1e-9
