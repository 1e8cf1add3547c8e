"""The object stream of continuous surveillance (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_sim.stream import PARKED, PATH_KINDS, ObjectStream, random_path, travel
from activesurv_sim.xytable import TABLE_RANGE
from activesurv_stages.errors import ConfigError


@pytest.mark.parametrize('kind', PATH_KINDS)
@pytest.mark.parametrize('seed', [0, 1, 2])
def test_every_path_kind_crosses_the_table_within_its_range_and_speed(
    kind: str, seed: int
) -> None:
    p = random_path(kind, np.random.default_rng(seed), speed=0.02, acceleration=0.02)
    (x0, x1), (y0, y1) = TABLE_RANGE
    assert np.all((p.xy[:, 0] >= x0) & (p.xy[:, 0] <= x1))
    assert np.all((p.xy[:, 1] >= y0) & (p.xy[:, 1] <= y1))
    speed = np.hypot(*np.diff(p.xy, axis=0).T) / np.diff(p.t)
    assert speed.max() <= 0.02 + 1e-6
    # From one end of the table to the other, at rest at both ends.
    assert abs(p.xy[-1, 0] - p.xy[0, 0]) > 0.4
    assert np.allclose(p.velocity(0.0), 0.0, atol=2e-3)
    assert np.allclose(p.velocity(p.duration), 0.0, atol=2e-3)


def test_a_stop_holds_still_for_its_dwell_and_a_reversal_goes_back() -> None:
    p = travel([[0.1, 0.1], [0.2, 0.1], [0.3, 0.1]], [0.02, 0.02], {1: 3.0}, 0.02)
    at_stop = np.flatnonzero(np.isclose(p.xy[:, 0], 0.2, atol=1e-9))
    assert p.t[at_stop[-1]] - p.t[at_stop[0]] >= 3.0 - 1e-9
    r = random_path('reversal', np.random.default_rng(4))
    dx = np.diff(r.xy[:, 0])
    assert (dx > 1e-9).any(), 'a reversal moves both ways along x'
    assert (dx < -1e-9).any(), 'a reversal moves both ways along x'


def test_the_stream_is_one_object_at_a_time_and_seeded() -> None:
    a = ObjectStream(7, arrival_interval=10.0, first_entry=1.0)
    b = ObjectStream(7, arrival_interval=10.0, first_entry=1.0)
    assert a.pass_at(0.5) is None
    assert not a.state(0.5).present
    assert np.allclose(a.state(0.5).top[:2], PARKED)
    a.pass_at(500.0)
    for prev, nxt in zip(a.passes, a.passes[1:], strict=False):
        assert nxt.entered >= prev.left + a.gap - 1e-9
        assert nxt.entered >= prev.entered + 10.0 - 1e-9
    assert [p.kind for p in a.passes[:5]] == [
        b.pass_at(p.entered + 0.1).kind for p in a.passes[:5]
    ]
    first = a.passes[0]
    s = a.state(first.entered + 1.0)
    assert s.present
    assert np.allclose(s.top[:2], first.path.position(1.0))


def test_a_stream_on_a_rig_has_the_tables_position_errors() -> None:
    from activesurv_common.mount import CameraMount
    from activesurv_sim.rig import nominal_rig, perturb_rig

    mounts = {'cam1': CameraMount('cam1', [0.02, -0.5, 0.05], 1.5707963)}
    rig = perturb_rig(nominal_rig(mounts, [0.25, 0.1, 1.25, 1.0, 0.0, 0.0, 0.0]), 3)
    exact = ObjectStream(7, first_entry=1.0)
    real = ObjectStream(7, first_entry=1.0, position_error=rig.table_offset)
    t = exact.pass_at(5.0).entered + 3.0  # type: ignore[union-attr]
    xy = exact.state(t).top[:2]
    off = real.state(t).top[:2] - xy
    assert np.allclose(off, rig.table_offset(float(xy[0]), float(xy[1])))
    assert 1e-7 < np.hypot(*off) < 2e-4  # Table I: 48 / 24 um
    assert np.allclose(real.state(0.5).top[:2], PARKED)  # no object: parked, no error


def test_bad_stream_settings_are_refused() -> None:
    with pytest.raises(ConfigError):
        ObjectStream(0, arrival_interval=0.0)
    with pytest.raises(ConfigError):
        ObjectStream(0, kinds=['zigzag'])
    with pytest.raises(ConfigError):
        random_path('zigzag', np.random.default_rng(0))


def test_a_scripted_stream_has_exactly_its_objects_in_their_lanes() -> None:
    from activesurv_sim.stream import table_from_parameters

    script = [
        {'enter': 3.0, 'slot': 1, 'path': {'type': 'line', 'points': [0.47, 0.15, 0.03, 0.15]}},
        {'enter': 1.0, 'slot': 0, 'path': {'type': 'line', 'points': [0.03, 0.05, 0.47, 0.05]}},
    ]
    s = ObjectStream(0, script=script)
    assert s.at_once == 2
    assert [(p.id, p.slot, p.entered) for p in s.passes] == [(1, 0, 1.0), (2, 1, 3.0)]
    assert [p.id for p in s.passes_at(5.0)] == [1, 2]
    oid, state = s.slot_state(1, 5.0)
    assert oid == 2
    assert state.top[0] < 0.47
    assert s.passes_at(1000.0) == []
    assert len(s.passes) == 2
    # The same from an xy_table node's parameters (a JSON list), and bad scripts refused.
    params = {
        'side_offset': [0.0, -0.03, -0.03], 'side_normal': [0.0, -1.0, 0.0], 'top_height': 0.08,
        'speed': 0.02, 'acceleration': 0.02, 'path_type': 'stream', 'stream_seed': 0,
        'arrival_interval': 30.0, 'start_time': 1.0, 'path_kinds': list(PATH_KINDS),
        'stream_script': '[{"enter": 1.0, "slot": 0, "path": {"type": "line", '
        '"points": [0.03, 0.05, 0.47, 0.05]}}]',
    }  # fmt: skip
    table = table_from_parameters(params)
    assert isinstance(table, ObjectStream)
    assert len(table.passes) == 1
    for bad, match in (
        ('not json', 'JSON'),
        ('[{"enter": -1, "path": {"type": "line", "points": [0, 0, 1, 0]}}]', 'enter'),
        ('[{"enter": 1, "path": {"type": "line", "points": [0.1, 0.1, 0.9, 0.1]}}]', 'leaves'),
        ('[{"enter": 1, "slot": 7, "path": {"type": "line", "points": [0, 0, 1, 0]}}]', 'slot'),
    ):
        with pytest.raises(ConfigError, match=match):
            table_from_parameters({**params, 'stream_script': bad})
    twice = [script[1], {**script[1], 'enter': 5.0}]
    with pytest.raises(ConfigError, match='share lane'):
        ObjectStream(0, script=twice)


def test_a_table_config_says_the_same_as_its_node_parameters() -> None:
    from activesurv_common.object_geometry import ObjectGeometry
    from activesurv_sim.stream import table_from_parameters
    from activesurv_sim.xytable import TableConfig, XYTable

    c = TableConfig(
        'parabola', (0.13, 0.05, 0.25, 0.09, 0.37, 0.05), start_time=0.5, enters_at_start=True,
        model=ObjectGeometry(0.07, (0.0, -0.02, -0.03), (0.0, -1.0, 0.0)),
    )  # fmt: skip
    direct = c.table()
    via = table_from_parameters(c.to_parameters())
    assert isinstance(via, XYTable)
    for t in (0.0, 0.6, 3.0, 9.0):
        a, b = direct.state(t), via.state(t)
        assert np.allclose(a.side, b.side)
        assert a.present == b.present
    with pytest.raises(ConfigError):
        TableConfig('spiral').path()
