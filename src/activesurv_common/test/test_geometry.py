"""Core tests of the shared geometry helpers (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.errors import GeometryError
from activesurv_common.geometry import (
    Transform,
    angle_between,
    matrix_from_quaternion,
    normal_from_quaternion,
    normal_to_rotation_covariance,
    quaternion_from_matrix,
    quaternion_from_normal,
    rot_x,
    rot_y,
    rot_z,
    rotation_between,
    unit,
)

unit_vectors = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(
    lambda v: np.linalg.norm(v) > 1e-3
)


@settings(max_examples=200, deadline=None)
@given(unit_vectors, unit_vectors)
def test_rotation_between_maps_a_onto_b(a: tuple, b: tuple) -> None:  # type: ignore[type-arg]
    R = rotation_between(a, b)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.allclose(R @ unit(a), unit(b), atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3))
def test_quaternion_round_trip(ax: float, ay: float, az: float) -> None:
    R = rot_z(az) @ rot_y(ay) @ rot_x(ax)
    q = quaternion_from_matrix(R)
    assert q[3] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0)
    assert np.allclose(matrix_from_quaternion(q), R, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(unit_vectors)
def test_normal_quaternion_round_trip(n: tuple) -> None:  # type: ignore[type-arg]
    assert np.allclose(normal_from_quaternion(quaternion_from_normal(n)), unit(n), atol=1e-9)


def test_a_transforms_quaternion_is_its_rotations_and_a_callers_copy() -> None:
    T = Transform.from_rt(rot_z(0.7) @ rot_x(0.2), [1.0, 2.0, 3.0])
    q = T.quaternion()
    assert np.allclose(q, quaternion_from_matrix(T.R))
    q[:] = 0.0  # the caller's copy: the transform keeps its own
    assert np.allclose(T.quaternion(), quaternion_from_matrix(T.R))
    assert T.__dict__['_quaternion'] is not q  # worked out once, held apart


def test_transform_compose_and_inverse() -> None:
    a = Transform.from_rt(rot_z(0.3), [1.0, 2.0, 3.0])
    b = Transform.from_rt(rot_x(-0.7), [0.1, 0.0, -0.2])
    p = np.array([0.3, -0.4, 0.5])
    assert np.allclose(a.compose(b).apply(p), a.apply(b.apply(p)))
    assert np.allclose(a.inverse().apply(a.apply(p)), p)
    with pytest.raises(GeometryError):
        Transform.from_rt(np.diag([1.0, 1.0, -1.0]), [0, 0, 0])


def test_rotation_covariance_of_normal() -> None:
    n = np.array([0.0, -1.0, 0.0])
    cov = np.diag([1e-4, 0.0, 4e-4])  # spread of n_x and n_z; n_y is second order
    rc = normal_to_rotation_covariance(n, cov, unobserved_variance=9.0)
    # Tilting about z moves n along x; tilting about x moves n along z; about y: unobserved.
    assert rc[2, 2] == pytest.approx(1e-4)
    assert rc[0, 0] == pytest.approx(4e-4)
    assert rc[1, 1] == pytest.approx(9.0)


def test_bad_inputs_raise() -> None:
    with pytest.raises(GeometryError, match='zero length'):
        unit([0, 0, 0])
    with pytest.raises(GeometryError, match='finite'):
        unit([np.nan, 0, 1])
    with pytest.raises(GeometryError):
        matrix_from_quaternion([0, 0, 0, 0])
    assert angle_between([1, 0, 0], [0, 1, 0]) == pytest.approx(np.pi / 2)


def test_bearing_is_the_angle_between_the_normal_and_the_line_to_the_camera() -> None:
    import math

    from activesurv_common.geometry import bearing, bearings

    n = [0.0, -1.0, 0.0]
    assert bearing([0.0, -0.5, 0.0], n) == 0.0
    assert abs(bearing([0.5, -0.5, 0.0], n) - math.pi / 4) < 1e-12
    assert abs(bearing([0.0, 0.5, 0.0], n) - math.pi) < 1e-12
    b = bearings([[0.0, -2.0, 0.0], [1.0, 0.0, 0.0]], [0.0, -3.0, 0.0])  # any length of normal
    assert abs(b[0]) < 1e-12
    assert abs(b[1] - math.pi / 2) < 1e-12


@pytest.mark.parametrize('angle', [0.0, 0.3, -0.3, 3.0, -3.0, math.pi, 4.0, -4.0, 7.0])
def test_a_rotation_about_z_knows_the_quaternion_its_matrix_gives(angle: float) -> None:
    T = Transform.about_z(angle, [0.1, -0.2, 0.3])
    np.testing.assert_allclose(T.R, rot_z(angle), atol=1e-15)
    np.testing.assert_allclose(T.quaternion(), quaternion_from_matrix(rot_z(angle)), atol=1e-12)
    np.testing.assert_array_equal(T.t, [0.1, -0.2, 0.3])


@pytest.mark.parametrize(
    ('angle', 't'), [(math.nan, [0, 0, 0]), (0.1, [0, math.inf, 0]), (0.1, [0, 0])]
)
def test_a_rotation_about_z_refuses_bad_values(angle: float, t: list[float]) -> None:
    with pytest.raises(GeometryError, match='finite angle and 3-vector'):
        Transform.about_z(angle, t)
