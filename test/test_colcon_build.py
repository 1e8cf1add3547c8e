"""The packages are real ament packages: colcon builds them and `ros2 run`'s target starts.

``ros2 run <pkg> <node>`` executes ``install/<pkg>/lib/<pkg>/<node>``; this test builds the
workspace with colcon (from PyPI) into a temporary directory, sources ``install/setup.bash``,
starts the fusion node from exactly that path, and checks it answers a capture request.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.graph, pytest.mark.slow]
# Every ament package of the source tree, read from the tree (not a list kept by hand).
PACKAGES = sorted(p.parent.name for p in (REPO / 'src').glob('*/package.xml'))


@pytest.fixture(scope='module')
def colcon_install(colcon_workspace: Path) -> Path:
    """The install space of the workspace built by colcon (started in the background by the
    root conftest when this module is collected; see ``colcon_workspace``)."""
    return colcon_workspace / 'install'


def test_every_package_is_installed_as_an_ament_package(colcon_install: Path) -> None:
    for pkg in PACKAGES:
        assert (colcon_install / pkg / 'share' / pkg / 'package.xml').exists(), pkg
        index = colcon_install / pkg / 'share' / 'ament_index' / 'resource_index' / 'packages'
        assert (index / pkg).exists(), pkg
    assert (colcon_install / 'activesurv_fusion' / 'lib' / 'activesurv_fusion' / 'fusion').exists()


def test_node_started_from_the_install_space_answers(
    colcon_install: Path, rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from activesurv_interfaces.msg import CaptureRequest, TargetEstimate

    exe = colcon_install / 'activesurv_fusion' / 'lib' / 'activesurv_fusion' / 'fusion'
    script = (
        f'source {colcon_install}/setup.bash && '
        f'python -c "import activesurv_fusion; print(activesurv_fusion.__file__)" && '
        f'exec {exe} --ros-args -p collect_timeout:=0.3'
    )
    env = dict(os.environ)
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env.get("PATH", "")}'
    proc = subprocess.Popen(
        ['bash', '-c', script],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    node = rclpy_context.create_node('colcon_probe')
    got: list[Any] = []
    try:
        pub = node.create_publisher(  # the blackboard's event QoS (fusion subscribes latched)
            CaptureRequest,
            'capture_request',
            QoSProfile(
                depth=10,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL,
            ),
        )
        node.create_subscription(
            TargetEstimate,
            'target_estimate',
            got.append,
            QoSProfile(
                depth=10,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL,
            ),
        )
        assert spin_until([node], lambda: pub.get_subscription_count() > 0, timeout=60.0), (
            'the installed fusion node never subscribed'
        )
        req = CaptureRequest(demand_index=42, camera_ids=['cam1'])
        req.demand_instant = node.get_clock().now().to_msg()
        pub.publish(req)
        assert spin_until([node], lambda: len(got) > 0, timeout=30.0)
        assert got[0].demand_index == 42
        assert got[0].status == TargetEstimate.STATUS_NO_OBSERVATIONS
    finally:
        node.destroy_node()
        os.killpg(proc.pid, signal.SIGINT)
        output, _ = proc.communicate(timeout=20)
    first_line = output.splitlines()[0]
    # The node's code came from the colcon install space, not from the editable venv install.
    assert first_line.startswith(str(colcon_install)), output
