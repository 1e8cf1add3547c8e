"""The import picture of the packages: common at the bottom, sim beside imaging, thin nodes.

Every import statement of every package module (function-level ones included) is read with
``ast``; these rules are the architecture the README's diagram draws.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
PACKAGES = (
    'activesurv_common',
    'activesurv_sim',
    'activesurv_imaging',
    'activesurv_prediction',
    'activesurv_dispatch',
    'activesurv_fusion',
    'activesurv_stages',
    'activesurv_bringup',
)
# Which of our packages each package may import (besides itself and the interfaces).
ALLOWED: dict[str, set[str]] = {
    'activesurv_common': set(),
    'activesurv_stages': {'activesurv_common'},
    'activesurv_prediction': {'activesurv_common'},
    'activesurv_fusion': {'activesurv_common'},
    'activesurv_dispatch': {'activesurv_common', 'activesurv_stages'},
    'activesurv_imaging': {'activesurv_common'},
    'activesurv_sim': {'activesurv_common', 'activesurv_stages'},
    'activesurv_bringup': set(PACKAGES),
}
OPENCV_USERS = {'activesurv_sim', 'activesurv_imaging', 'activesurv_bringup'}
ROS_TOP_LEVEL = ('rclpy', 'activesurv_interfaces', 'builtin_interfaces', 'rosgraph_msgs')
NODE_LINE_LIMIT = 200


def modules(package: str) -> Iterator[Path]:
    yield from sorted((SRC / package / package).rglob('*.py'))


def imports(path: Path) -> set[str]:
    """Top-level modules and first-level submodules imported by ``path``."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
    return out


def is_ros_shell(package: str, path: Path) -> bool:
    """Modules allowed to touch rclpy and messages: nodes, conversions, common.ros, bringup."""
    rel = path.relative_to(SRC / package / package)
    return (
        package == 'activesurv_bringup'
        or rel.parts[0] == 'ros'
        or path.stem.endswith('_node')
        or path.stem == 'conversions'
    )


@pytest.mark.parametrize('package', PACKAGES)
def test_package_imports_only_what_sits_below_it(package: str) -> None:
    bad = []
    for path in modules(package):
        for name in imports(path):
            top = name.split('.')[0]
            ours = top.startswith('activesurv_') and top not in (package, 'activesurv_interfaces')
            if ours and top not in ALLOWED[package]:
                bad.append(f'{path.relative_to(SRC)} imports {name}')
    assert not bad, '\n'.join(bad)


@pytest.mark.parametrize('package', PACKAGES)
def test_only_sim_imaging_and_bringup_use_opencv(package: str) -> None:
    users = [p for p in modules(package) if any(n.split('.')[0] == 'cv2' for n in imports(p))]
    if package not in OPENCV_USERS:
        assert not users, f'{package} imports OpenCV in {users}'


@pytest.mark.parametrize('package', PACKAGES)
def test_cores_import_no_rclpy_and_no_messages(package: str) -> None:
    bad = []
    for path in modules(package):
        if is_ros_shell(package, path):
            continue
        for name in imports(path):
            top = name.split('.')[0]
            if top in ROS_TOP_LEVEL or top.endswith('_msgs'):
                bad.append(f'{path.relative_to(SRC)} imports {name}')
    assert not bad, '\n'.join(bad)


def test_nodes_are_thin() -> None:
    long = [
        f'{p.relative_to(SRC)}: {n} lines'
        for package in PACKAGES
        for p in modules(package)
        if p.stem.endswith('_node') and (n := len(p.read_text().splitlines())) > NODE_LINE_LIMIT
    ]
    assert not long, '\n'.join(long)


def test_every_node_uses_the_shared_entry_point_and_topics() -> None:
    for package in PACKAGES:
        for p in modules(package):
            if not p.stem.endswith('_node'):
                continue
            text = p.read_text()
            assert 'run_node(' in text, f'{p.name}: main() should be run_node(...)'
            assert 'rclpy.init(' not in text, f'{p.name} initialises rclpy itself'
            tree = ast.parse(text)
            for call in ast.walk(tree):
                # A bare depth (create_publisher(T, topic, 10)) instead of a named profile.
                if (
                    isinstance(call, ast.Call)
                    and isinstance(call.func, ast.Attribute)
                    and call.func.attr in ('create_publisher', 'create_subscription')
                ):
                    assert not any(
                        isinstance(a, ast.Constant) and isinstance(a.value, int) for a in call.args
                    ), f'{p.name}: a bare QoS depth at line {call.lineno}'
