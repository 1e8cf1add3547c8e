"""Every conversions module, round-tripped: a core value -> message -> the core value of the
package that reads it (the way the graph passes them), with hand-chosen values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from activesurv_common.geometry import Transform, rot_z
from activesurv_common.ros.conversions import (
    joint_vector,
    object_state_vector,
    pose_from_transform,
    sec_to_time,
    time_to_sec,
    transform_from_pose,
    vector3,
)

pytestmark = pytest.mark.cross  # cores of several packages, no ROS

COV6 = np.diag([1e-8, 2e-8, 3e-8, 1e-6, 2e-6, 3e-6])


def test_stamps_and_poses() -> None:
    for t in (0.0, 1.5, 12.000000001, 1795436420.25):
        assert time_to_sec(sec_to_time(t)) == pytest.approx(t, abs=1e-9)
    assert (sec_to_time(-1.0).sec, sec_to_time(math.nan).sec) == (0, 0)  # invalid -> zero stamp
    T = Transform(rot_z(0.7), np.array([0.1, -0.2, 0.3]))
    back = transform_from_pose(pose_from_transform(T))
    assert pytest.approx(T.R) == back.R
    assert back.t == pytest.approx(T.t)


def test_prediction_horizon_to_dispatch_demands() -> None:
    from activesurv_dispatch.conversions import horizon_to_demands
    from activesurv_prediction.conversions import horizon_to_msg
    from activesurv_prediction.demands import DemandPrediction
    from activesurv_prediction.tracker import TrackState

    p = DemandPrediction(3, 7.25, np.array([0.2, 0.05, 0.05]), np.array([0.0, -1.0, 0.0]), COV6)
    msg = horizon_to_msg([p], TrackState.CONFIRMED, 6.0, 'world')
    (d,) = horizon_to_demands(msg)
    assert (d.index, d.time) == (3, pytest.approx(7.25))
    assert d.position == pytest.approx(p.position)
    assert d.normal == pytest.approx(p.normal)
    assert d.covariance == pytest.approx(COV6)


def test_a_horizons_orientations_follow_each_demands_normal() -> None:
    """The horizon keeps the quaternions of the normals it has seen: each demand's is still
    its own normal's."""
    from activesurv_common.geometry import quaternion_from_normal
    from activesurv_prediction.conversions import horizon_to_msg
    from activesurv_prediction.demands import DemandPrediction
    from activesurv_prediction.tracker import TrackState

    normals = [np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0])]
    preds = [
        DemandPrediction(i, 7.0 + i, np.array([0.2, 0.05, 0.05]), n, COV6)
        for i, n in enumerate(normals)
    ]
    for _ in range(2):  # the second horizon from what the first one kept
        msg = horizon_to_msg(preds, TrackState.CONFIRMED, 6.0, 'world')
        for d, n in zip(msg.demands, normals, strict=True):
            o = d.pose.pose.orientation
            assert [o.x, o.y, o.z, o.w] == list(quaternion_from_normal(n))
            assert list(d.pose.covariance) == list(COV6.reshape(-1))


def test_a_plans_camera_poses_are_each_mounts_own() -> None:
    """A plan's desired camera poses are kept per mount and joints: two rigs with the same
    camera and joints but mounted apart get their own poses, as computed afresh."""
    from types import SimpleNamespace

    from activesurv_common.mount import CameraMount
    from activesurv_dispatch.conversions import plan_to_msg
    from activesurv_dispatch.planner import Assignment, Plan, Role

    q = np.array([0.1, 0.3])
    for base_x in (0.0, 0.25, 0.0):
        mount = CameraMount(
            'cam1',
            np.array([base_x, -0.4, 0.3]),
            pitch=0.4,
            linear_axis=np.array([1.0, 0.0, 0.0]),
            linear_joint='cam1_linear',
            rotary_joint='cam1_rotary',
        )
        sensor = SimpleNamespace(camera_id='cam1', joint_names=mount.joint_names, mount=mount)
        setup = SimpleNamespace(sensors=(sensor,))
        plan = Plan(1.0, 0, {'cam1': Assignment('cam1', Role.ASSIGNED, 0, q, 2.0)}, 2.0, False)
        msg = plan_to_msg(plan, setup, 0, 'world')  # type: ignore[arg-type]
        expected = pose_from_transform(mount.pose_from_joints(q))
        assert msg.assignments[0].desired_camera_pose == expected


def test_dispatch_goal_to_stage_items_and_capture_to_fusion_request() -> None:
    from activesurv_dispatch.conversions import capture_to_request, command_to_goal
    from activesurv_dispatch.motion import Capture, StageCommand
    from activesurv_dispatch.planner import Demand
    from activesurv_fusion.conversions import request_fields
    from activesurv_stages.conversions import goal_items

    cmd = StageCommand(
        'cam1', ('cam1_x', 'cam1_yaw'), np.array([0.01, -0.2]), np.array([0.025, 0.2]), 5.0
    )
    assert goal_items(command_to_goal(cmd, 4.0)) == [
        ('cam1_x', pytest.approx(0.01), pytest.approx(0.025)),
        ('cam1_yaw', pytest.approx(-0.2), pytest.approx(0.2)),
    ]
    demand = Demand(4, 9.0, np.array([0.3, 0.06, 0.05]), np.array([0.0, -1.0, 0.0]), COV6)
    msg = capture_to_request(Capture(demand, ('cam2', 'cam4')), 8.7, 'world')
    index, t, cams, prior = request_fields(msg)
    assert (index, t, cams, prior) == (4, pytest.approx(9.0), ('cam2', 'cam4'), (0.0, -1.0, 0.0))


def test_imaging_observation_to_fusion_answer() -> None:
    from activesurv_common.statuses import ObservationStatus
    from activesurv_fusion.collector import Outcome
    from activesurv_fusion.conversions import observation_to_answer
    from activesurv_imaging.conversions import observation_to_msg
    from activesurv_imaging.observation import Observation, failed

    obs = Observation(
        'cam3',
        2,
        5.0,
        ObservationStatus.OK,
        position=np.array([0.21, 0.07, 0.05]),
        normal=np.array([0.0, -1.0, 0.0]),
        covariance=COV6,
    )
    answer = observation_to_answer(observation_to_msg(obs))
    assert answer.outcome is Outcome.OK
    assert answer.reading is not None
    assert answer.reading.position == pytest.approx(obs.position)
    assert answer.reading.covariance == pytest.approx(COV6)
    bad = failed('cam3', 2, 5.0, ObservationStatus.NOT_FOUND, 'no marker in the image')
    answer = observation_to_answer(observation_to_msg(bad))
    assert (answer.outcome, answer.reason) == (Outcome.FAILED, 'no marker in the image')


def test_fusion_result_to_estimate_and_pose() -> None:
    from activesurv_fusion.collector import Answer, DemandBatch, Outcome, resolve
    from activesurv_fusion.conversions import result_to_estimate, result_to_pose
    from activesurv_fusion.pose_fusion import PoseReading

    p = np.array([0.2, 0.06, 0.05])
    answers = {
        c: Answer(c, Outcome.OK, PoseReading.create(c, p, (0.0, -1.0, 0.0), COV6))
        for c in ('cam1', 'cam2')
    }
    result = resolve(DemandBatch(1, 6.0, ('cam1', 'cam2'), answers))
    est = result_to_estimate(result, 'world')
    assert vector3(est.position) == pytest.approx(p)
    assert np.array(est.covariance).reshape(6, 6) == pytest.approx(COV6 / 2.0)  # eq. 2
    assert est.fused_visibility == pytest.approx(2.0 / np.linalg.norm(COV6))
    pose = result_to_pose(result, 'world')
    assert pose is not None
    assert transform_from_pose(pose.pose.pose).R[:, 2] == pytest.approx([0.0, -1.0, 0.0])


def test_stage_joint_state_and_sim_object_state() -> None:
    from activesurv_sim.ros.table_messages import object_state_msg
    from activesurv_sim.xytable import ObjectState
    from activesurv_stages.conversions import joint_state

    msg = joint_state(['cam1_x', 'cam1_yaw'], [0.02, 0.3], [0.0, 0.1], sec_to_time(2.0))
    assert joint_vector(msg, ['cam1_yaw', 'cam1_x']) == pytest.approx([0.3, 0.02])
    assert joint_vector(msg, ['cam2_yaw']) is None
    s = ObjectState(
        np.array([0.2, 0.1, 0.08]),
        np.array([0.2, 0.07, 0.05]),
        np.array([0.0, -1.0, 0.0]),
        np.array([0.02, 0.0, 0.0]),
        True,
    )
    v = object_state_vector(object_state_msg(s, sec_to_time(2.0), 'world'))
    assert v == pytest.approx(np.concatenate([s.top, s.side, s.side_normal]))
