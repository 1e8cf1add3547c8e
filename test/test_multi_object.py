"""Several objects at once, the pieces: an imager measures the demanded one of two markers in
view, the overhead locator sees every top marker, the stream puts objects side by side."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.camera_model import dynamic_camera, overhead_camera
from activesurv_common.sensor_model import SensorModel
from activesurv_common.statuses import ObservationStatus
from activesurv_imaging.capture import CaptureCore, ImagerConfig
from activesurv_imaging.overhead import overhead_fixes
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise, look_at
from activesurv_sim.stream import ObjectStream

pytestmark = pytest.mark.cross  # cores of several packages, no ROS

NORMAL = np.array([0.0, -1.0, 0.0])
MINE = np.array([0.25, 0.10, 0.05])
OTHER = np.array([0.285, 0.10, 0.05])  # another object's marker beside it, 35 mm away


def test_the_imager_measures_the_demanded_marker_of_two_in_view() -> None:
    cam = dynamic_camera('cam1')
    pose = look_at(MINE + np.array([0.0, -0.8, 0.0]), MINE)
    scene = Scene(tuple(Plate.disc(p, NORMAL, 0.0125, 0.015) for p in (MINE, OTHER)))
    frame = Renderer(cam).render(pose, scene, SensorNoise(0.0, 0.0, 0.0))
    for target, told in [(MINE, True), (OTHER, True), (MINE, False)]:
        core = CaptureCore(
            ImagerConfig('cam1', several_objects=told),
            pose,
            SensorModel.load(None),
            lambda g: g,
            cam,
        )
        core.request(0, 1.0, NORMAL, position=target if told else None)
        core.add_frame(1.0, frame)
        (obs,) = core.poll(1.1)
        if not told:  # without a prediction to go by, two markers are refused
            assert obs.status is ObservationStatus.REJECTED
            assert '2 markers' in obs.reason
            continue
        assert obs.status is ObservationStatus.OK, obs.reason
        assert obs.position is not None
        assert np.linalg.norm(obs.position - target) < 1e-3


def test_the_overhead_locator_finds_every_top_marker() -> None:
    cam = overhead_camera()
    pose = look_at([0.25, 0.1, 1.25], [0.25, 0.1, 0.0], up=(0.0, 1.0, 0.0))
    tops = [np.array([0.1, 0.05, 0.08]), np.array([0.3, 0.12, 0.08]), np.array([0.4, 0.06, 0.08])]
    scene = Scene(tuple(Plate.disc(p, [0, 0, 1], 0.0125, 0.03) for p in tops))
    frame = Renderer(cam).render(pose, scene, SensorNoise(0.0, 0.0, 0.0))
    fixes = overhead_fixes(frame, cam, pose, 0.08, 0.0125)
    xy = sorted((tuple(f.xy) for f in fixes if f.xy is not None), key=lambda v: v[0])
    assert len(xy) == 3
    for got, want in zip(xy, tops, strict=True):
        assert np.hypot(got[0] - want[0], got[1] - want[1]) < 1e-3


def test_a_stream_of_two_at_once_overlaps_in_lanes_30_mm_apart() -> None:
    s = ObjectStream(3, 30.0, 1.0, at_once=2)
    ts = np.arange(0.0, 400.0, 0.5)
    counts = [len(s.passes_at(t)) for t in ts]
    assert max(counts) == 2
    assert np.mean(np.array(counts) == 2) > 0.3  # overlapping most of the time
    directions = set()
    for t in ts:
        ps = s.passes_at(t)
        for p in ps:
            path = p.path.xy
            directions.add(bool(path[-1, 0] > path[0, 0]))
        if len(ps) == 2:
            a, b = (p.path.position(t - p.entered) for p in ps)
            assert np.hypot(*(a - b)) >= 0.03 - 1e-9
            assert ps[0].slot != ps[1].slot
    assert directions == {True, False}  # both ways
    # One at a time is the stream it always was.
    one = ObjectStream(3, 30.0, 1.0)
    assert max(len(one.passes_at(t)) for t in ts) == 1


def test_the_scaling_study_serves_one_object_with_k_and_copies_cameras_apart() -> None:
    from activesurv_dispatch.sensors import load_setup
    from activesurv_studies.scaling import eight_cameras, run_scaling

    setup = eight_cameras(load_setup(motion='fast'))
    ids = [s.camera_id for s in setup.sensors]
    assert ids == [f'cam{i}' for i in range(1, 9)]
    joints = [j for s in setup.sensors for j in s.joint_names]
    assert len(joints) == len(set(joints))  # every copy has stages of its own
    assert np.allclose(setup.sensor('cam5').mount.base - setup.sensor('cam1').mount.base,
                       [0.06, 0.0, 0.0])  # fmt: skip
    one = run_scaling(1, 4, seconds=40.0)
    assert one['demands'] >= 8
    assert one['cameras_per_demand'] > 2.5  # k = 3 nearly always, one object
    two = run_scaling(3, 4, seconds=40.0)
    assert two['cameras_per_demand'] < one['cameras_per_demand']  # fewer as objects grow
