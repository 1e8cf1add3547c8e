"""Every node ships ``config/<node>.yaml`` with exactly its declared parameters and defaults,
and a node started with that file comes up (the file is a valid ``--params-file``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'scripts'))

from node_configs import NODES, main  # noqa: E402


@pytest.mark.meta
def test_node_configs_are_current() -> None:
    assert main(['--check']) == 0, 'run .venv/bin/python scripts/node_configs.py'


@pytest.mark.meta
def test_each_config_holds_the_declared_defaults() -> None:
    import importlib

    for node, (package, module) in NODES.items():
        data = yaml.safe_load((ROOT / 'src' / package / 'config' / f'{node}.yaml').read_text())
        values = data[node]['ros__parameters']
        params = importlib.import_module(f'{package}.{module}').PARAMS
        declared = {p.name: p.default for p in params if not hasattr(p.default, 'name')}
        assert values == declared, node


@pytest.mark.cli
def test_a_node_starts_with_its_config_file(tmp_path: Path) -> None:
    # The fusion node has no required parameter: with its shipped file it must come up and
    # stop cleanly on SIGINT.
    import signal

    cfg = ROOT / 'src' / 'activesurv_fusion' / 'config' / 'fusion.yaml'
    proc = subprocess.Popen(
        [
            sys.executable,
            '-m',
            'activesurv_fusion.fusion_node',
            '--ros-args',
            '--params-file',
            str(cfg),
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        proc.wait(timeout=4.0)
        raise AssertionError(f'fusion exited early: {proc.stderr.read() if proc.stderr else ""}')
    except subprocess.TimeoutExpired:
        pass
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=20.0) == 0
