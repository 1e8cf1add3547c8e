"""The evaluation sits beneath the orchestrator: importing it loads no rclpy and no graph."""

from __future__ import annotations

import subprocess
import sys

MODULES = ('report', 'runs', 'session', 'session_report', 'results', 'records', 'tracking')


def test_importing_the_evaluation_loads_neither_rclpy_nor_the_orchestrator() -> None:
    code = (
        'import sys\n'
        + ''.join(f'import activesurv_evaluation.{m}\n' for m in MODULES)
        + 'bad = sorted(m for m in sys.modules if m.split(".")[0] in '
        "('rclpy', 'activesurv_bringup', 'activesurv_launch') or m.endswith('_msgs'))\n"
        'print(bad)\n'
    )
    out = subprocess.run(
        [sys.executable, '-c', code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == '[]', out.stdout
