"""The imager on frames made with the simulator's optics (issue 33, item 3): depth of field,
a motion streak over the exposure and a gamma curve, the camera's response told to the imager
as its calibration carries it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from activesurv_common.camera_model import dynamic_camera
from activesurv_imaging.marker_pose import MeasurementStatus, measure_marker
from activesurv_sim.optics import Optics, frame_optics
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise, look_at

CAM = dynamic_camera('cam1')


def test_the_imager_measures_through_the_simulators_optics() -> None:
    """A marker 6 cm behind the focus at f/2.8, moving 20 mm/s over 10 ms, gamma 2.2 (told to
    the imager as the calibration does): still a fraction of a millimetre."""
    o = Optics(f_number=2.8, focus_distance=0.44, exposure_time=0.01, gamma=2.2)
    T = look_at([0.05, -0.5, 0.08], [0.0, 0.0, 0.05])
    p = np.array([0.0, 0.0, 0.05])
    v = np.array([0.02, 0.0, 0.0])
    lens = frame_optics(CAM, o, T, p, ((T, p - 0.005 * v), (T, p + 0.005 * v)))
    assert lens.defocus_sigma > 1.5
    scene = Scene((Plate.disc(p, [0.0, -1.0, 0.0], 0.0125, 0.03),))
    img = Renderer(CAM).render(T, scene, SensorNoise(), np.random.default_rng(3), lens)
    told = replace(CAM, gamma=2.2, exposure_time=0.01)
    m = measure_marker(img, told, 0.0125, T.inverse().rotate([0.0, -1.0, 0.0]))
    assert m.status is MeasurementStatus.OK, m.reason
    assert m.pose is not None
    centre = T.apply(m.pose.center)
    assert float(np.linalg.norm(centre - p)) < 0.1e-3
