"""Commissioning one camera of a perturbed rig from rendered checkerboard views: the
calibration finds what the rig really is, starting from nothing but nominal values."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_bringup.board_views import board_corners, collect_stations, simulated_look
from activesurv_bringup.rigs import nominal
from activesurv_common.mount import CameraMount
from activesurv_imaging.commissioning import commission_camera, order_like, pixel_error
from activesurv_imaging.errors import CalibrationError
from activesurv_sim.board import BoardFixture
from activesurv_sim.rig import perturb_rig


@pytest.mark.parametrize(('seed', 'camera_id'), [(5, 'cam3'), (8, 'cam4')])
def test_a_perturbed_camera_is_commissioned_from_nominal_values(seed: int, camera_id: str) -> None:
    nom = nominal()
    rig = perturb_rig(nom, seed)
    fixture = BoardFixture()
    n = nom.camera(camera_id)
    stations = collect_stations(
        simulated_look(rig, camera_id, fixture, seed), n.camera, n.mount, fixture
    )
    assert sum(len(s.sightings) for s in stations) >= 30
    model, mount, rms = commission_camera(n.camera, n.mount, stations, board_corners(fixture))
    truth = rig.camera(camera_id)
    assert rms < 0.3
    assert abs(model.fx / truth.camera.fx - 1) < 1e-3  # nominal was up to 2 % off
    assert np.all(np.abs(mount.base - truth.mount.base) < 0.5e-3)
    assert np.all(np.abs(mount.offset - truth.mount.offset) < 0.5e-3)
    # the error that reaches measurements: world points through both models, in pixels
    worst = max(
        pixel_error(truth.camera, truth.true_mount(), model, mount, s.joints) for s in stations
    )
    assert worst < 1.0
    before = max(pixel_error(truth.camera, truth.true_mount(), n.camera, n.mount, s.joints)
                 for s in stations)  # fmt: skip
    assert before > 20.0


def test_a_reversed_corner_order_is_put_right() -> None:
    expected = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    assert np.array_equal(order_like(expected[::-1], expected), expected)
    assert np.array_equal(order_like(expected, expected), expected)


def test_too_few_stations_are_refused() -> None:
    n = nominal().camera('cam2')
    with pytest.raises(CalibrationError, match='station'):
        commission_camera(n.camera, n.mount, [], board_corners(BoardFixture()))
    assert isinstance(n.mount, CameraMount)
