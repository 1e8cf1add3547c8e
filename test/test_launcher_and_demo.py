"""Orchestration: the launcher starts node processes, notices a dead node, and the demo runs."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest

from activesurv_bringup.errors import NodeDiedError
from activesurv_launch.launcher import (
    Launcher,
    NodeSpec,
    node_command,
    write_params_file,
)

pytestmark = pytest.mark.graph


def test_params_file_and_command_line(tmp_path: Path) -> None:
    spec = NodeSpec(
        'fusion',
        'activesurv_fusion.fusion_node',
        namespace='lab',
        parameters={'collect_timeout': 1.5},
        remappings={'target_pose': 'pose'},
    )
    params = write_params_file(spec, tmp_path)
    assert params is not None
    assert '/lab/fusion' in params.read_text()
    cmd = node_command(spec, params)
    assert cmd[:3] == [sys.executable, '-m', 'activesurv_fusion.fusion_node']
    assert '__ns:=/lab' in cmd
    assert 'target_pose:=pose' in cmd
    assert '--params-file' in cmd


def test_launcher_reports_a_dead_required_node(tmp_path: Path) -> None:
    spec = NodeSpec('fusion', 'activesurv_fusion.fusion_node')
    with Launcher([spec], workdir=tmp_path) as launcher:
        launcher.wait_alive(1.0)
        launcher.processes['/fusion'].kill(signal.SIGKILL)
        launcher.processes['/fusion'].process.wait(10)
        with pytest.raises(NodeDiedError, match='/fusion died'):
            launcher.check()


def test_launcher_stops_nodes_cleanly(tmp_path: Path) -> None:
    with Launcher(
        [NodeSpec('fusion', 'activesurv_fusion.fusion_node')], workdir=tmp_path
    ) as launcher:
        launcher.wait_alive(1.0)
    codes = launcher.stop()
    assert codes == {'/fusion': 0}  # SIGINT -> the node flushed and exited normally


def test_a_stop_while_a_node_imports_ends_it_cleanly_once_started(tmp_path: Path) -> None:
    # The launcher holds SIGINT in the child until the node's stop handlers are in place: a stop
    # that comes while the node still imports rclpy and numpy is not Python's KeyboardInterrupt
    # mid-import (exit status -2, what a busy CI host once saw) but a clean stop.
    launcher = Launcher([NodeSpec('fusion', 'activesurv_fusion.fusion_node')], workdir=tmp_path)
    launcher.start()
    codes = launcher.stop()  # at once, long before the node has imported its modules
    assert codes == {'/fusion': 0}
    log = (tmp_path / 'fusion.log').read_text()
    assert 'KeyboardInterrupt' not in log


def test_a_ctrl_c_while_stopping_leaves_no_node_running(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    specs = [NodeSpec(f'fusion{i}', 'activesurv_fusion.fusion_node') for i in range(3)]
    launcher = Launcher(specs, workdir=tmp_path)
    launcher.start()
    launcher.wait_alive(1.0)
    last = launcher.processes['/fusion2']  # stopped first
    real_stop = type(last).stop

    def interrupted(self: object, timeout: float = 5.0) -> int | None:
        if self is last:
            raise KeyboardInterrupt  # Ctrl-C while the launcher waits for it
        return real_stop(self, timeout)  # type: ignore[arg-type]

    monkeypatch.setattr(type(last), 'stop', interrupted)
    with pytest.raises(KeyboardInterrupt):
        launcher.stop()
    monkeypatch.undo()
    for proc in launcher.processes.values():
        proc.process.wait(10)  # every node is gone, the interrupted one too
        assert not proc.alive()
