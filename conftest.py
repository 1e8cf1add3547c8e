"""Session-wide isolation for every test that touches ROS.

Each pytest session gets its own ROS_DOMAIN_ID (held with a lock file so that two sessions on
this shared machine never pick the same one), localhost-only discovery, and ROS_HOME/ROS_LOG_DIR
in a temporary directory. This runs before any test module imports rclpy.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

import pytest

from activesurv_launch.domains import claim_domain_id

_held: list[IO[str]] = []
_owned_home: list[Path] = []


def _claim_domain_id() -> int:
    domain, handle = claim_domain_id()  # the lock is held for the session
    _held.append(handle)
    return domain


def pytest_configure(config: pytest.Config) -> None:
    # Each process that runs tests isolates itself once: a plain session, or each worker of a
    # parallel one (``make test``: pytest-xdist), whose tests must not hear the other worker's
    # nodes. A nested pytest (or a child) keeps its parent's: the marker holds who set it.
    me = os.environ.get('PYTEST_XDIST_WORKER', 'main')
    if os.environ.get('ACTIVESURV_TEST_ISOLATED') in (me, '1'):
        return
    ros_home = Path(tempfile.mkdtemp(prefix='activesurv-test-ros-'))
    os.environ['ROS_DOMAIN_ID'] = str(_claim_domain_id())
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ['ROS_HOME'] = str(ros_home)
    os.environ['ROS_LOG_DIR'] = str(ros_home / 'log')
    os.environ['ACTIVESURV_LOCK_DIR'] = str(ros_home / 'locks')  # the rigs' port locks
    os.environ['ACTIVESURV_TEST_ISOLATED'] = me
    if me == 'main':  # the session's own files (colcon workspace, groups), its workers' too
        os.environ['ACTIVESURV_TEST_SESSION_DIR'] = str(ros_home)
        os.environ['ACTIVESURV_COLCON_WS'] = str(ros_home / 'colcon')
    # Runs are told their rig's truth unless a test asks otherwise: commissioning a rig takes
    # minutes (test_commission.py runs it, and the default, on purpose).
    os.environ.setdefault('ACTIVESURV_CALIBRATION', 'truth')
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    _owned_home.append(ros_home)


ROOT = Path(__file__).resolve().parent
# The tiers (docs/development.md): a package's own tests (src/*/test) are its core, unmarked, or
# in-process nodes (``node``); test/ holds what spans packages, each test with its tier.
TIERS = ('graph', 'node', 'cli', 'cross', 'meta')


# Run last in the graph worker of a parallel session: the lab's cameras render at 15 Hz each and
# want the machine to themselves, which they have once the other worker's tests are done.
HEAVY_LAST = (
    'test_several_hosts.py', 'test_image_load.py', 'test_surveil.py', 'test_measure_delay.py',
    'test_hardware_lab.py', 'test_lab.py',
)  # fmt: skip

# Graph-tier modules the other worker runs once its own tests are done (a unit of their own,
# last in its queue), beside the graph worker's runs: ten minutes of graph tests in one worker
# left the other idle for seven. They and the heavy ones above never run at once
# (:func:`_machine_lock`): the lab still has the machine to itself.
SIDE_GRAPH = ('test_set_c.py', 'test_faults.py')


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Every test shows its tier: refused at collection otherwise. In a parallel session
    (``--dist loadgroup``) the graph tier runs in one worker, one run at a time, heaviest last,
    while the other worker runs the rest a module at a time (a module's fixtures built once)."""
    wrong = []
    for item in items:
        path = Path(str(item.path)).resolve()
        marks = {m.name for m in item.iter_markers()}
        if path.is_relative_to(ROOT / 'test'):
            if not marks & set(TIERS):
                wrong.append(f'{item.nodeid}: no tier marker (one of {", ".join(TIERS)})')
        elif path.is_relative_to(ROOT / 'src') and marks & {'graph', 'cli', 'cross', 'meta'}:
            wrong.append(f'{item.nodeid}: a package test is its core or node tier, not {marks}')
    if wrong:
        raise pytest.UsageError('tests without their tier:\n  ' + '\n  '.join(wrong))
    if os.environ.get('PYTEST_XDIST_WORKER') and getattr(config.option, 'loadgroup', False):
        _one_graph_worker(items)
    elif not config.option.collectonly and any(i.path.name == COLCON_TEST for i in items):
        _start_colcon_build()


def _one_graph_worker(items: list[pytest.Item]) -> None:
    """Order a worker's collection (graph tier first, the colcon build's test and the heaviest
    last, the rest after) and write each test's group where the controller's scheduler reads
    it: xdist's own ``xdist_group`` rewrites node ids, which pytest 9 no longer lets it do."""

    def rank(item: pytest.Item) -> tuple[int, int]:
        name = item.path.name
        if item.get_closest_marker('graph') is None:
            return (2, 0)
        if name in SIDE_GRAPH:
            return (3, 0)
        if name == COLCON_TEST:  # its build, started with the session, is done by then
            return (1, -1)
        return (1, HEAVY_LAST.index(name)) if name in HEAVY_LAST else (0, 0)

    items.sort(key=rank)  # stable: the order within a file is kept

    def group(item: pytest.Item) -> str:
        if item.get_closest_marker('graph') is None:
            return item.nodeid.split('::')[0]
        return 'graph_side' if item.path.name in SIDE_GRAPH else 'graph'

    groups = {i.nodeid: group(i) for i in items}
    path = _groups_file()
    if path is None:
        return  # a session isolated by hand: the scheduler groups by module
    part = path.with_name(f'{path.name}.{os.getpid()}')
    part.write_text(json.dumps(groups))
    part.replace(path)  # both workers write the same groups; either file is whole


def _groups_file() -> Path | None:
    session = os.environ.get('ACTIVESURV_TEST_SESSION_DIR')
    return Path(session) / 'xdist_groups.json' if session else None


@pytest.fixture(scope='module', autouse=True)
def _machine_lock(request: pytest.FixtureRequest) -> Iterator[None]:
    """In a parallel session, a module of :data:`HEAVY_LAST` or :data:`SIDE_GRAPH` holds the
    session's machine lock while it runs (its module fixtures too: autouse ones come first)."""
    session = os.environ.get('ACTIVESURV_TEST_SESSION_DIR')
    parallel = session and os.environ.get('PYTEST_XDIST_WORKER')
    if not parallel or request.path.name not in (*HEAVY_LAST, *SIDE_GRAPH):
        yield
        return
    import fcntl

    with (Path(session) / 'machine.lock').open('a') as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)  # released when the file closes
        yield


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """``--dist loadgroup`` with the groups the workers wrote: the graph tier is one unit of
    work (one worker, one run at a time), every other module a unit of its own."""
    if config.getvalue('dist') != 'loadgroup':
        return None
    from xdist.scheduler import LoadScopeScheduling

    class GraphWorker(LoadScopeScheduling):  # type: ignore[misc]
        groups: dict[str, str] | None = None

        def _split_scope(self, nodeid: str) -> str:
            if self.groups is None:  # read once every worker has collected
                path = _groups_file()
                self.groups = {}
                if path is not None and path.exists():
                    self.groups = json.loads(path.read_text())
            return self.groups.get(nodeid) or nodeid.split('::')[0]

    return GraphWorker(config, log)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_node_collection_finished(node: Any, ids: list[str]) -> None:
    """A parallel session's controller starts the colcon build once, as a plain session does
    at collection, where every worker finds it."""
    if any(COLCON_TEST in i for i in ids):
        _start_colcon_build()


# The colcon build of the workspace (test/test_colcon_build.py) is a minute of CMake and
# rosidl generation that waits for nothing: it starts in the background when that test is
# collected, beside the package tests that run first, and the test waits for it. It writes its
# exit code to ``rc`` beside the workspace, which a worker of a parallel session waits for.
COLCON_TEST = 'test_colcon_build.py'
_colcon: dict[str, Any] = {}


def _colcon_ws() -> Path:
    if not os.environ.get('ACTIVESURV_COLCON_WS'):  # a session isolated by hand
        os.environ['ACTIVESURV_COLCON_WS'] = tempfile.mkdtemp(prefix='activesurv-colcon-')
    return Path(os.environ['ACTIVESURV_COLCON_WS'])


def _start_colcon_build() -> None:
    colcon = Path(sys.executable).parent / 'colcon'
    ws = _colcon_ws()
    if _colcon or not colcon.exists() or (ws.exists() and any(ws.iterdir())):
        return  # started already (here or by the controller), or the test says what is missing
    ws.mkdir(parents=True, exist_ok=True)
    (ws / 'src').symlink_to(ROOT / 'src')
    env = dict(os.environ)
    env['AMENT_PREFIX_PATH'] = env['CMAKE_PREFIX_PATH'] = sys.prefix
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env.get("PATH", "")}'
    log = (ws / 'build.log').open('w')
    build = [str(colcon), 'build', '--base-paths', 'src', '--event-handlers', 'console_direct-']
    proc = subprocess.Popen(
        ['/bin/sh', '-c', '"$@"; echo $? > rc.part && mv rc.part rc', 'sh', *build],
        cwd=ws,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,  # its own process group: stopped as one at the session's end
    )
    _colcon.update(ws=ws, proc=proc, log=log)


@pytest.fixture(scope='session')
def colcon_workspace() -> Path:
    """The workspace colcon built in the background (its ``install/`` beside ``src``)."""
    import time

    _start_colcon_build()
    ws = _colcon_ws()
    assert (ws / 'src').exists(), 'colcon is not installed in the venv (make setup)'
    deadline = time.monotonic() + 900.0
    while not (ws / 'rc').exists():
        assert time.monotonic() < deadline, 'colcon build still running after 900 s'
        time.sleep(0.5)
    rc = int((ws / 'rc').read_text())
    text = (ws / 'build.log').read_text(errors='replace')
    assert rc == 0, f'colcon build failed ({rc}):\n{text[-6000:]}'
    return ws


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Stop a colcon build still running, remove its workspace; remove this session's ROS_HOME
    when every test passed, keep its logs for a failure."""
    if _colcon:
        proc = _colcon['proc']
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        _colcon['log'].close()
        shutil.rmtree(_colcon['ws'], ignore_errors=True)
        _colcon.clear()
    if not _owned_home:
        return
    if exitstatus == 0 and os.environ.get('ACTIVESURV_KEEP_TEST_ROS_HOME') != '1':
        shutil.rmtree(_owned_home[0], ignore_errors=True)
    else:
        print(f'\nROS logs of this session kept in {_owned_home[0]}')


def pytest_report_header(config: pytest.Config) -> str:
    return (
        f'ROS isolation: ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID")} '
        f'discovery={os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")} '
        f'ROS_HOME={os.environ.get("ROS_HOME")}'
    )


@pytest.fixture(scope='session')
def rclpy_context() -> Iterator[Any]:
    """rclpy initialised once for the session (in-process node tests)."""
    import rclpy

    rclpy.init()
    try:
        yield rclpy
    finally:
        rclpy.try_shutdown()


@pytest.fixture
def spin_until(rclpy_context: Any) -> Callable[..., bool]:
    """Spin the given nodes until ``predicate()`` holds or ``timeout`` seconds pass."""
    import time

    from rclpy.executors import SingleThreadedExecutor

    def _spin(nodes: list[Any], predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
        executor = SingleThreadedExecutor()
        for node in nodes:
            executor.add_node(node)
        deadline = time.monotonic() + timeout
        try:
            while time.monotonic() < deadline:
                if predicate():
                    return True
                executor.spin_once(timeout_sec=0.05)
            return predicate()
        finally:
            for node in nodes:
                executor.remove_node(node)
            executor.shutdown()

    return _spin


@pytest.fixture(scope='session')
def wait_for_file() -> Callable[..., bool]:
    """Wait until ``activesurv lab`` has written its hardware file ``path`` and reported ready
    (every camera streams: ``ready`` beside the file); False if it died first."""
    import time

    def wait(path: Path, proc: subprocess.Popen[str], timeout: float = 60.0) -> bool:
        deadline = time.monotonic() + timeout
        while not (path.exists() and (path.parent / 'ready').exists()):
            if proc.poll() is not None or time.monotonic() > deadline:
                return False
            time.sleep(0.1)
        return True

    return wait
