"""A node started with a bad parameter (``--ros-args -p`` or a YAML file) exits with status 1 and
one line on stderr naming the parameter: the same checks as a later ``ros2 param set``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.cli  # each node script alone, as a process

CASES = [
    ('activesurv_imaging.imager_node', 'marker_radius:=-1.0', 'marker_radius'),
    ('activesurv_imaging.imager_node', 'marker_radius:=abc', 'marker_radius'),
    ('activesurv_sim.sim_camera_node', 'supersample:=0', 'supersample'),
    ('activesurv_prediction.predictor_node', 'measurement_std:=-0.001', 'measurement_std'),
    ('activesurv_dispatch.dispatcher_node', 'k:=0', 'k'),
    ('activesurv_fusion.fusion_node', 'z_sigma:=-3.0', 'z_sigma'),
    ('activesurv_sim.sim_stage_node', 'publish_rate:=-5.0', 'publish_rate'),
    ('activesurv_sim.xy_table_node', 'real_time_factor:=0.0', 'real_time_factor'),
]


@pytest.mark.parametrize(('module', 'assignment', 'name'), CASES)
def test_bad_parameter_at_startup_is_one_line_error(
    module: str, assignment: str, name: str
) -> None:
    r = subprocess.run(
        [sys.executable, '-m', module, '--ros-args', '-p', assignment],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert 'Traceback' not in r.stderr, r.stderr[-2000:]
    assert len(lines) == 1, lines
    assert 'error:' in lines[0]
    assert name in lines[0]


def test_bad_parameter_in_a_yaml_file(tmp_path: Path) -> None:
    params = tmp_path / 'imager.yaml'
    params.write_text('imager:\n  ros__parameters:\n    frame_timeout: -2.0\n')
    r = subprocess.run(
        [
            sys.executable,
            '-m',
            'activesurv_imaging.imager_node',
            '--ros-args',
            '--params-file',
            str(params),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 1, r.stderr[-2000:]
    assert 'frame_timeout' in r.stderr
    assert 'Traceback' not in r.stderr
