"""The one kinematics: the batched poses the dispatcher scores are the poses every other user
(renderer, imager) gets one at a time."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.mount import CameraMount

finite = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def mounts(draw: st.DrawFn) -> CameraMount:
    linear = draw(st.booleans())
    axis = np.array([draw(finite), draw(finite), draw(finite)])
    if linear and np.linalg.norm(axis) < 1e-3:
        axis = np.array([1.0, 0.0, 0.0])
    return CameraMount(
        'cam1',
        np.array([draw(finite), draw(finite), draw(finite)]),
        draw(st.floats(-3.2, 3.2)),
        draw(st.floats(-0.5, 0.5)),
        np.array([draw(finite) * 0.05 for _ in range(3)]),
        axis / np.linalg.norm(axis) if linear else None,
        'cam1_x' if linear else None,
        'cam1_yaw',
    )


@settings(max_examples=200, deadline=None)
@given(mounts(), st.lists(st.tuples(finite, st.floats(-3.2, 3.2)), min_size=1, max_size=8))
def test_batched_poses_are_the_single_poses(
    mount: CameraMount, qs: list[tuple[float, float]]
) -> None:
    q = np.array([(lin, yaw) if mount.linear_axis is not None else (yaw,) for lin, yaw in qs])
    centres, rotations = mount.poses_from_joints(q)
    for i, row in enumerate(q):
        T = mount.pose_from_joints(row)
        assert np.allclose(centres[i], T.t, atol=1e-12)
        assert np.allclose(rotations[i], T.R, atol=1e-12)
