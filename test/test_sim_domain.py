"""A simulated run never reaches a real rig: without ROS_DOMAIN_ID set it takes a free DDS domain
of its own, so nothing it publishes (stage goals above all) appears on the default domain 0,
where a lab's stage_bridge nodes would listen."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

ACTIVESURV = str(Path(sys.executable).parent / 'activesurv')
pytestmark = [pytest.mark.graph, pytest.mark.slow]


def test_a_simulated_run_without_a_domain_stays_off_domain_0(tmp_path: Path) -> None:
    import rclpy
    from rclpy.context import Context

    env = dict(os.environ)
    env.pop('ROS_DOMAIN_ID')
    ctx = Context()
    rclpy.init(context=ctx, domain_id=0)
    watcher = rclpy.create_node('rig_side_watcher', context=ctx)
    seen: set[str] = set()
    run = subprocess.Popen(
        [ACTIVESURV, 'experiment', '--set', 'A', '--system', 'fast', '--calibration', 'truth',
         '--out', str(tmp_path / 'run')],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 300.0
        while run.poll() is None and time.monotonic() < deadline:
            seen.update(name for name, _ in watcher.get_topic_names_and_types())
            time.sleep(0.5)
        out = run.communicate(timeout=60)[0]
    finally:
        if run.poll() is None:
            run.kill()
        watcher.destroy_node()
        rclpy.shutdown(context=ctx)
    assert run.returncode == 0, out[-3000:]
    m = re.search(r'simulated run on ROS domain (\d+)', out)
    assert m, out[:500]
    assert int(m.group(1)) != 0
    ours = {t for t in seen if 'stage/goal' in t or t in ('/capture_request', '/clock')}
    assert not ours, f'the simulated run published on domain 0: {sorted(ours)}'
