"""The import picture of the packages: common at the bottom, sim beside imaging, thin nodes.

Every import statement of every package module (function-level ones included) is read with
``ast``; these rules are the architecture docs/node-graph.md's diagram draws.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

pytestmark = pytest.mark.meta

SRC = Path(__file__).resolve().parents[1] / 'src'
# Every Python ament package of the source tree (the interfaces are CMake).
PACKAGES = tuple(
    sorted(
        p.parent.name
        for p in SRC.glob('activesurv_*/setup.py')
        if (p.parent / p.parent.name).is_dir()
    )
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
    'activesurv_launch': {'activesurv_common'},
    'activesurv_recording': {'activesurv_common'},
    # Paths and the object model are the simulator's; a real table runs them too.
    'activesurv_hardware': {'activesurv_common', 'activesurv_stages', 'activesurv_sim'},
    'activesurv_liveview': {
        'activesurv_common',
        'activesurv_recording',
        'activesurv_dispatch',
        'activesurv_stages',
    },
    # Evaluation of recorded runs: beneath the orchestrator, no ROS graph.
    'activesurv_evaluation': {
        'activesurv_common',
        'activesurv_dispatch',
        'activesurv_hardware',
        'activesurv_liveview',
        'activesurv_recording',
        'activesurv_sim',
    },
    # Offline studies drive the cores without a graph (the dispatch scaling study: stages too;
    # the clairvoyant study reads a recorded run).
    'activesurv_studies': {
        'activesurv_evaluation',
        'activesurv_recording',
        'activesurv_common',
        'activesurv_dispatch',
        'activesurv_imaging',
        'activesurv_prediction',
        'activesurv_sim',
        'activesurv_stages',
    },
    'activesurv_bringup': set(PACKAGES),
}
OPENCV_USERS = {
    'activesurv_liveview',  # frames drawn for the report and the live view
    'activesurv_sim',
    'activesurv_imaging',
    'activesurv_bringup',
    'activesurv_hardware',
    'activesurv_studies',
}
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
    """Modules allowed to touch rclpy and messages: nodes, conversions, a package's ``ros``
    subpackage (common's, the launcher's container and composition), bringup (the orchestrator)."""
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


# Third-party Python modules and the rosdep keys a package.xml names them by.
ROSDEP = {
    'numpy': 'python3-numpy',
    'yaml': 'python3-yaml',
    'cv2': 'python3-opencv',
    'scipy': 'python3-scipy',
    'matplotlib': 'python3-matplotlib',
    'serial': 'python3-serial',
    'numba': 'python3-numba',
}
# rclpy's own packages come with it; pip-only libraries live in requirements.txt.
IMPLIED = {'rclpy', 'ament_index_python'}


def manifest_depends(package: str) -> set[str]:
    text = (SRC / package / 'package.xml').read_text()
    return set(re.findall(r'<(?:exec_)?depend>([^<]+)</(?:exec_)?depend>', text))


def imported_depends(package: str) -> set[str]:
    out: set[str] = set()
    for path in modules(package):
        for name in imports(path):
            top = name.split('.')[0]
            if top == package:
                continue
            if top.startswith('activesurv_') or top.endswith(('_msgs', '_srvs', '_interfaces')):
                out.add(top)
            elif top == 'rclpy':
                out.add('rclpy')
            elif top in ROSDEP:
                out.add(ROSDEP[top])
    return out


@pytest.mark.parametrize('package', PACKAGES)
def test_manifests_declare_exactly_what_the_code_imports(package: str) -> None:
    declared = manifest_depends(package) - IMPLIED
    used = imported_depends(package) - IMPLIED
    assert not used - declared, f'{package}/package.xml lacks {sorted(used - declared)}'
    assert not declared - used, f'{package}/package.xml declares unused {sorted(declared - used)}'


def module_name(package: str, path: Path) -> str:
    rel = path.relative_to(SRC / package).with_suffix('')
    parts = rel.parts[:-1] if rel.name == '__init__' else rel.parts
    return '.'.join(parts)


def module_level_imports(path: Path, known: set[str]) -> set[str]:
    """Our modules imported at module level (not in functions, not under TYPE_CHECKING)."""
    out: set[str] = set()
    for node in ast.parse(path.read_text()).body:
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f'{node.module}.{a.name}' for a in node.names]
        out.update(n for n in names if n in known)
    return out


def test_no_import_circles() -> None:
    graph: dict[str, set[str]] = {}
    paths = {module_name(pkg, p): p for pkg in PACKAGES for p in modules(pkg)}
    known = set(paths)
    for name, path in paths.items():
        graph[name] = module_level_imports(path, known) - {name}
    # Tarjan-free: a depth-first search that reports the first back edge as a circle.
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph[n]):
            if state.get(m) == 1:
                return stack[stack.index(m) :] + [m]
            if m not in state and (found := visit(m)):
                return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state and (circle := visit(n)):
            pytest.fail('import circle: ' + ' -> '.join(circle))


def test_no_package_holds_over_a_quarter_of_the_source() -> None:
    lines = {pkg: sum(len(p.read_text().splitlines()) for p in modules(pkg)) for pkg in PACKAGES}
    total = sum(lines.values())
    big = {pkg: n / total for pkg, n in lines.items() if n > total / 4}
    assert not big, f'packages over a quarter of the source: {big}'
    # The orchestration is thin: evaluation, studies and the cores hold the rest.
    share = lines['activesurv_bringup'] / total
    assert share < 0.2, f'activesurv_bringup holds {share:.1%} of the source (limit: a fifth)'


def test_project_modules_are_imported_at_the_top() -> None:
    """Function-level imports of project modules hide circles and make a module's needs hard to
    see; only a CLI (``cli.py``: it answers --help and refuses bad arguments before the heavy
    modules load) defers them. Heavy optional libraries (matplotlib, stonesoup, foxglove) may
    be deferred anywhere."""
    bad = []
    for pkg in PACKAGES:
        for path in modules(pkg):
            if path.name == 'cli.py':
                continue
            tree = ast.parse(path.read_text())
            top = set(map(id, tree.body))
            for node in ast.walk(tree):
                names = (
                    [node.module or '']
                    if isinstance(node, ast.ImportFrom)
                    else [a.name for a in node.names]
                    if isinstance(node, ast.Import)
                    else []
                )
                if (
                    any(n.startswith('activesurv_') for n in names)
                    and id(node) not in top
                    and not _under_type_checking(tree, node)
                ):
                    bad.append(f'{path.relative_to(SRC)}:{node.lineno} imports {names[0]}')
    assert not bad, '\n'.join(bad)


def _under_type_checking(tree: ast.Module, node: ast.AST) -> bool:
    for stmt in tree.body:
        if (
            isinstance(stmt, ast.If)
            and 'TYPE_CHECKING' in ast.unparse(stmt.test)
            and any(n is node for n in ast.walk(stmt))
        ):
            return True
    return False


def _only_forwards(tree: ast.Module) -> bool:
    """A module whose body is imports (and a docstring, ``__all__``) only: it forwards names."""
    body = [
        n
        for n in tree.body
        if not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))
        and not (isinstance(n, ast.ImportFrom) and n.module == '__future__')
    ]
    imports_ = [n for n in body if isinstance(n, (ast.Import, ast.ImportFrom))]
    rest = [
        n
        for n in body
        if n not in imports_
        and not (
            isinstance(n, ast.Assign)
            and all(isinstance(t, ast.Name) and t.id == '__all__' for t in n.targets)
        )
    ]
    return bool(imports_) and not rest


@pytest.mark.parametrize('package', PACKAGES)
def test_no_module_only_forwards_names(package: str) -> None:
    """When a module moves, its users move with it: no module is left that only re-exports."""
    bad = [
        str(p.relative_to(SRC))
        for p in modules(package)
        if _only_forwards(ast.parse(p.read_text(), str(p)))
    ]
    assert not bad, f'modules that only forward names: {bad}'


FUNCTION_LINE_LIMIT = 100


def test_no_function_does_several_jobs() -> None:
    """Functions over ~100 lines do several jobs: split them (tests excepted)."""
    long = []
    for package in PACKAGES:
        for p in modules(package):
            for node in ast.walk(ast.parse(p.read_text(), str(p))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    n = (node.end_lineno or node.lineno) - node.lineno + 1
                    if n > FUNCTION_LINE_LIMIT:
                        long.append(f'{p.relative_to(SRC)}: {node.name} {n} lines')
    assert not long, '\n'.join(long)


def _loaded_by(modules: tuple[str, ...], heavy: tuple[str, ...]) -> list[str]:
    """Which of ``heavy`` a fresh interpreter has loaded once it imported ``modules``."""
    import json
    import subprocess
    import sys

    found = f'sorted(m for m in {heavy!r} if m in sys.modules)'
    code = f'import json, sys, {", ".join(modules)}\nprint(json.dumps({found}))'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    return list(json.loads(out.stdout))


def test_reading_a_command_line_rig_or_hardware_file_loads_no_renderer_or_commissioning() -> None:
    """An orchestrator reads its arguments, rig and hardware file before it starts a graph:
    numba (the renderer's kernels, 0.3 s) and commissioning's modules (0.9 s) took 1.2 s of
    every run's start so (docs/performance.md)."""
    readers = (
        'activesurv_bringup.cli',
        'activesurv_bringup.arguments',
        'activesurv_bringup.rig.choice',
        'activesurv_hardware.hardware_file',
        'activesurv_sim.rig',
        'activesurv_sim.board',
        'activesurv_sim.optics',
    )
    assert (
        _loaded_by(readers, ('numba', 'scipy.optimize', 'activesurv_bringup.rig.commission')) == []
    )


def test_an_orchestrator_starts_a_graph_without_the_imaging_kernels() -> None:
    """The experiment, its graph and a hardware run's graph write the imagers' parameters
    (``imager_config``); the imaging itself (OpenCV, numba: 0.38 s of import) runs in the
    camera containers only, and loading it in the orchestrator took a core from their start."""
    graphs = (
        'activesurv_bringup.experiments.experiment',
        'activesurv_bringup.experiments.graph',
        'activesurv_bringup.experiments.hardware_graph',
    )
    assert _loaded_by(graphs, ('numba', 'cv2', 'activesurv_imaging.capture')) == []
