"""A frame rendered ahead and released at its instant on the camera's own trigger."""

from __future__ import annotations

import numpy as np

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.mount import CameraMount
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_sim.sim_camera import SimulatedCamera

T = 5.0
# top marker xyz, side marker xyz, side normal xyz: the object at the origin, facing -y.
STATE = np.array([0.0, 0.03, 0.08, 0.0, 0.0, 0.05, 0.0, -1.0, 0.0])


def _camera() -> SimulatedCamera:
    mount = CameraMount('cam1', np.array([0.02, -0.5, 0.05]), 1.5708, 0.0, np.zeros(3))
    return SimulatedCamera(dynamic_camera('cam1'), mount, ObjectGeometry(), seed=1)


def _planned(sim: SimulatedCamera, yaw: float = 0.0) -> None:
    sim.plan(T, STATE, [yaw])
    assert sim.render_ahead(T)


def test_the_frame_goes_out_at_its_instant_when_the_stage_state_of_the_instant_holds() -> None:
    sim = _camera()
    _planned(sim)
    assert sim.release(T) is None, 'released before the stage state of the instant was known'
    sim.joints.add(T, [0.0])  # the stage's state for the instant, published ahead
    frame = sim.release(T)
    assert frame is not None
    assert frame.shape == (sim.camera.height, sim.camera.width)
    assert sim.release(T) is None  # once
    # The same frame as one rendered from the states of the instant (pixels up to the noise).
    other = _camera()
    other.objects.add(T, STATE)
    other.joints.add(T, [0.0])
    late, ahead = other.frame_at(T)
    assert not ahead
    assert np.abs(frame.astype(float) - late.astype(float)).mean() < 2.0
    assert frame.astype(float).std() > 5.0  # the marker is in it


def test_a_new_goal_since_the_frame_was_rendered_holds_it_back() -> None:
    sim = _camera()
    _planned(sim)
    sim.joints.add(T, [0.02])  # a new goal moved the stage's state of the instant
    assert sim.release(T) is None
    sim.objects.add(T, STATE)  # then the instant's states arrive: rendered anew
    _, ahead = sim.frame_at(T)
    assert not ahead


def test_a_released_frame_is_checked_against_the_tables_own_state() -> None:
    sim = _camera()
    _planned(sim)
    sim.joints.add(T, [0.0])
    assert sim.release(T) is not None
    assert not sim.released_differs(T)  # the table's state of T not here yet
    sim.add_object(T, STATE)
    assert not sim.released_differs(T)
    assert not sim.released_differs(T)  # checked once

    moved = _camera()
    _planned(moved)
    moved.joints.add(T, [0.0])
    assert moved.release(T) is not None
    moved.add_object(T, STATE + np.r_[0.001, 0.0, 0.0, 0.001, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert moved.released_differs(T)


def test_a_static_camera_needs_no_stage_state() -> None:
    from activesurv_common.geometry import Transform
    from activesurv_sim.render import look_at

    T_cam: Transform = look_at([0.0, -0.5, 0.05], [0.0, 0.0, 0.05])
    sim = SimulatedCamera(dynamic_camera('cam1'), T_cam, ObjectGeometry(), seed=1)
    sim.plan(T, STATE)
    assert sim.render_ahead(T)
    assert sim.release(T) is not None


def test_a_frame_rendered_ahead_goes_out_in_the_messages_built_with_it() -> None:
    from activesurv_common.ros.conversions import (
        camera_info_from_model,
        gray_to_image,
        sec_to_time,
    )
    from activesurv_sim.ros.frame_messages import FrameMessages

    sim = _camera()
    _planned(sim)
    ahead = sim.ahead_frame(T)
    assert ahead is not None
    messages = FrameMessages(sim.camera, 'cam1_optical_frame')
    messages.prepare(T, ahead)
    sim.joints.add(T, [0.0])
    frame = sim.release(T)
    assert frame is ahead
    assert sim.ahead_frame(T) is None
    info, image = messages(T, frame)
    assert messages.prepared == 1  # the ones built ahead
    stamp = sec_to_time(T)
    assert image == gray_to_image(frame, 'cam1_optical_frame', stamp)
    assert info == camera_info_from_model(sim.camera, 'cam1_optical_frame', stamp)
    # Other pixels for the same instant (a frozen camera's): built now, from those pixels.
    messages.prepare(T, ahead)
    frozen = np.zeros_like(ahead)
    _, other = messages(T, frozen)
    assert messages.prepared == 1
    assert bytes(other.data) == frozen.tobytes()


def test_a_lane_first_heard_of_in_a_plan_is_rendered_with_the_others() -> None:
    """A camera hearing the states around its instants only may know no lane yet when the
    plans of an instant come, one message per lane: the frame is rendered with every lane."""
    sim = _camera()
    parked = STATE + np.r_[[100.0, 100.0, 0.0] * 2, [0.0] * 3]  # the empty lane's place
    sim.plan(T, STATE, [0.0], slot=0)
    assert sim.render_ahead(T)  # with lane 0, the only one known so far
    sim.plan(T, parked, slot=1)  # lane 1's plan: rendered again, with both
    assert sim.render_ahead(T)
    sim.joints.add(T, [0.0])
    assert sim.release(T) is not None
    sim.add_object(T, STATE, 0)
    sim.add_object(T, parked, 1)
    assert not sim.released_differs(T), 'the frame showed lane 0 alone'
