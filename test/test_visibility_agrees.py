"""Dispatch scores a fusion subset before the capture with the same eq. 2 that fusion reports
after it: for the same cameras and covariances the two visibilities are equal."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.geometry import rot_z
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.visibility import fused_visibility
from activesurv_fusion.collector import Answer, DemandBatch, Outcome, resolve
from activesurv_fusion.pose_fusion import PoseReading

pytestmark = pytest.mark.cross  # cores of several packages, no ROS


@pytest.mark.parametrize('k', [1, 2, 3, 4])
def test_dispatch_and_fusion_visibility_agree(k: int) -> None:
    model = SensorModel.load()
    rng = np.random.default_rng(k)
    cams = [f'cam{i + 1}' for i in range(k)]
    covs = [
        model.world_covariance(0.45 + 0.05 * i, np.radians(20.0 + 10.0 * i), rot_z(0.3 * i))
        for i in range(k)
    ]
    truth = np.array([0.25, 0.07, 0.05])
    answers = {}
    for cid, R in zip(cams, covs, strict=True):
        # Readings a fraction of a sigma from the truth: every camera agrees, none is faulty.
        p = truth + 0.1 * np.sqrt(np.diag(R)[:3]) * rng.uniform(-1, 1, 3)
        reading = PoseReading.create(cid, p, np.array([0.0, -1.0, 0.0]), R)
        answers[cid] = Answer(cid, Outcome.OK, reading)
    result = resolve(DemandBatch(0, 5.0, tuple(cams), answers))
    assert result.fused is not None
    assert sorted(result.fused.cameras_used) == cams
    assert result.fused_visibility == pytest.approx(fused_visibility(covs), rel=1e-9)
