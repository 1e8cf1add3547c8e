"""Image annotations: the fitted ellipse, its centre and the chosen normal, or the failure, as
ImageMarkers stamped like the image (no ROS graph)."""

from __future__ import annotations

import math

import numpy as np

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.geometry import Transform
from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.annotations import annotation_shapes, ellipse_points
from activesurv_imaging.conversions import annotation_markers
from activesurv_imaging.ellipse import Ellipse
from activesurv_imaging.observation import Observation, failed


def _observation() -> Observation:
    cam = dynamic_camera()
    pose = Transform.identity()  # camera at the world origin, looking along world z
    position = np.array([0.01, -0.005, 0.5])
    centre = cam.project(position[None, :])[0]
    return Observation(
        'cam1',
        7,
        12.5,
        ObservationStatus.OK,
        position=position,
        normal=np.array([0.0, -0.6, -0.8]),
        ellipse=Ellipse(centre, (40.0, 30.0), 0.3),
        camera_pose=pose,
    )


def test_ellipse_centre_and_normal() -> None:
    cam = dynamic_camera()
    obs = _observation()
    shapes = annotation_shapes(obs, cam.project, image_size=(cam.width, cam.height))
    assert [s.kind for s in shapes] == ['ellipse', 'centre', 'normal']
    pts = np.array(shapes[0].points)
    assert np.allclose(pts[0], pts[-1])  # closed
    # Every drawn point lies on the fitted ellipse.
    assert obs.ellipse is not None
    c, s = math.cos(0.3), math.sin(0.3)
    d = pts - obs.ellipse.center
    u, v = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
    assert np.allclose((u / 40.0) ** 2 + (v / 30.0) ** 2, 1.0)
    # The normal starts at the marker centre's projection and points up the image (its camera
    # y component is negative: y is down).
    start, end = np.array(shapes[2].points)
    assert np.allclose(start, obs.ellipse.center, atol=1e-6)
    assert end[1] < start[1]
    markers = annotation_markers(shapes, obs.stamp, 'cam1_optical_frame', obs.demand_index)
    assert [m.type for m in markers] == [1, 0, 2]  # LINE_STRIP, CIRCLE, LINE_LIST
    assert all(m.header.frame_id == 'cam1_optical_frame' for m in markers)
    assert all((m.header.stamp.sec, m.header.stamp.nanosec) == (12, 500_000_000) for m in markers)
    assert len(markers[0].points) == 49
    assert markers[1].position.x == obs.ellipse.center[0]
    assert (
        len(np.unique(ellipse_points(np.zeros(2), np.array([2.0, 1.0]), 0.0, 8)[:-1], axis=0)) == 8
    )


def test_a_failure_is_drawn_with_its_reason() -> None:
    obs = failed('cam2', 3, 4.0, ObservationStatus.NOT_FOUND, 'no contrast in the image')
    shapes = annotation_shapes(obs, None, image_size=(640, 480))
    assert len(shapes) == 1
    assert shapes[0].kind == 'status'
    assert not shapes[0].ok
    assert shapes[0].points == ((320.0, 240.0),)
    (m,) = annotation_markers(shapes, obs.stamp, 'cam2_optical_frame', 3)
    assert m.ns == 'demand 3: not_found: no contrast in the image'
    assert m.outline_color.r > 0.9
    assert m.outline_color.g < 0.5
