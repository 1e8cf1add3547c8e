"""Obstacles and lines of sight (no ROS)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from activesurv_common.occlusion import (
    Box,
    Cylinder,
    ObstacleError,
    blocked,
    inside,
    obstacles_from_list,
    obstacles_to_list,
)

BOX = Box((0.25, 0.3, 0.05), (0.1, 0.04, 0.1))
CYL = Cylinder((0.1, 0.3, 0.06), 0.02, 0.12)


def test_a_line_of_sight_through_a_box_or_a_cylinder_is_blocked_and_one_past_it_is_not() -> None:
    camera = np.array([0.25, 0.6, 0.05])
    assert blocked(camera, [0.25, 0.0, 0.05], [BOX]).tolist() == [True]
    assert blocked(camera, [0.25, 0.0, 0.2], [BOX]).tolist() == [False]  # over it
    assert blocked(camera, [0.25, 0.5, 0.05], [BOX]).tolist() == [False]  # ends before it
    cam2 = np.array([0.1, 0.6, 0.05])
    assert blocked(cam2, [0.1, 0.0, 0.05], [CYL]).tolist() == [True]
    assert blocked(cam2, [0.13, 0.0, 0.05], [CYL]).tolist() == [True]  # clips the side
    assert blocked(cam2, [0.2, 0.0, 0.05], [CYL]).tolist() == [False]
    assert blocked(cam2, [0.1, 0.0, 0.5], [CYL]).tolist() == [False]  # over the top
    # A marker on a box's face is not hidden by that box from the side it faces.
    assert blocked([0.25, 0.6, 0.05], [0.25, 0.32, 0.05], [BOX]).tolist() == [False]
    # No obstacles: nothing is blocked; many segments at once.
    assert blocked(np.zeros((5, 3)), np.ones((5, 3)), []).tolist() == [False] * 5


def test_obstacles_round_trip_and_bad_ones_are_refused_with_a_reason() -> None:
    items = [
        {'kind': 'box', 'centre': [0.25, 0.3, 0.05], 'size': [0.1, 0.04, 0.1]},
        {'kind': 'cylinder', 'centre': [0.1, 0.3, 0.06], 'radius': 0.02, 'height': 0.12},
    ]
    obs = obstacles_from_list(items)
    assert obs == (BOX, CYL)
    assert obstacles_to_list(obs) == items
    assert obstacles_from_list(None) == ()
    for bad, words in [
        ([{'kind': 'cone', 'centre': [0, 0, 0]}], 'kind'),
        ([{'kind': 'box', 'centre': [0, 0, 0]}], 'missing'),
        ([{'kind': 'box', 'centre': [0, 0, 0], 'size': [1, 0, 1]}], 'size y'),
        ([{'kind': 'box', 'centre': [0, 'nan', 0], 'size': [1, 1, 1]}], 'finite'),
        ([{'kind': 'cylinder', 'centre': [0, 0, 0], 'radius': -1, 'height': 1}], 'radius'),
        ({'kind': 'box'}, 'list'),
    ]:
        with pytest.raises(ObstacleError, match=words):
            obstacles_from_list(bad)


coord = st.floats(-0.5, 0.5, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(
    st.tuples(coord, coord, coord),
    st.tuples(coord, coord, coord),
    st.booleans(),
)
def test_blocked_agrees_with_dense_sampling_of_the_segment(
    a: tuple[float, float, float], b: tuple[float, float, float], box: bool
) -> None:
    obstacle = (
        Box((0.0, 0.0, 0.0), (0.3, 0.2, 0.25)) if box else Cylinder((0.0, 0.0, 0.0), 0.15, 0.3)
    )
    s = np.linspace(1e-3, 1 - 1e-3, 4001)[:, None]
    points = np.asarray(a) + s * (np.asarray(b) - np.asarray(a))
    hit = bool(np.any(inside(points, [obstacle], margin=-1e-4)))  # clearly inside somewhere
    grazing = bool(np.any(inside(points, [obstacle], margin=1e-4)))
    got = bool(blocked(a, b, [obstacle])[0])
    if hit:
        assert got
    elif not grazing:
        assert not got


def test_a_segment_along_a_box_face_with_a_subnormal_slope_warns_nothing() -> None:
    """A direction component too small to divide by (subnormal) is the parallel case: no
    overflow warning, and the same answer as the exactly parallel segment."""
    box = [Box((0.0, 0.0, 0.0), (0.3, 0.2, 0.25))]
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        for x, expected in ((0.0, True), (0.5, False)):
            tiny = blocked((x, -1.0, 0.01), (x + 1e-310, 1.0, 0.01), box)
            exact = blocked((x, -1.0, 0.01), (x, 1.0, 0.01), box)
            assert bool(tiny[0]) is bool(exact[0]) is expected
