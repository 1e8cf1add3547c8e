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


def test_a_demand_after_the_last_truth_is_kept_without_a_stale_truth() -> None:
    """A stop that ends the table first leaves a last demand after its last state: its truth
    is unknown (not that state held, 1 mm off at 20 mm/s 50 ms on), the demand is kept when
    anything of it was heard, and a demand the run never reached ends the records."""
    from activesurv_common.timeseries import TimeSeries
    from activesurv_evaluation.runs import demand_truth

    truth = TimeSeries(6)
    for t in (7.35, 7.45):  # the grid's states; the instant 7.5 got none
        truth.add(t, np.array([0.02 * t, 0.0, 0.08, 0.0, -1.0, 0.0]))
    between = demand_truth(truth, 7.4, ended=False, heard_of=True)
    assert between is not None
    assert abs(between[0] - 0.02 * 7.4) < 1e-12  # interpolated
    exact = demand_truth(truth, 7.45, ended=True, heard_of=True)
    assert exact is not None
    assert exact[0] == 0.02 * 7.45
    after = demand_truth(truth, 7.5, ended=True, heard_of=True)
    assert after is not None
    assert np.all(np.isnan(after)), f'a stale truth: {after}'
    assert demand_truth(truth, 7.5, ended=True, heard_of=False) is None  # never reached
    gap = demand_truth(truth, 7.5, ended=False, heard_of=False)
    assert gap is not None
    assert np.all(np.isnan(gap))
