"""Every way out stops: the rig's e-stop from a second terminal (``activesurv stop``), and a run
ended by SIGTERM or SIGKILL leaves no process behind (graph tier: real processes over DDS)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from activesurv_bringup.rig.lab import camera_controller, table_controller
from activesurv_bringup.specs import bridge_spec
from activesurv_dispatch.sensors import load_setup
from activesurv_launch.launcher import Launcher

pytestmark = pytest.mark.graph

BIN = Path(sys.executable).parent
ACTIVESURV = str(BIN / 'activesurv')


def _processes_mentioning(text: str) -> list[int]:
    """Pids of live processes whose command line contains ``text`` (not this one)."""
    pids = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmd = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')
            state = (entry / 'stat').read_text().rsplit(')', 1)[1].split()[0]
        except OSError:
            continue
        if text in cmd and state != 'Z':
            pids.append(int(entry.name))
    return pids


@pytest.fixture
def rig_with_bridges(tmp_path: Path) -> Iterator[tuple[Path, list[str]]]:
    """A hardware file whose controllers are emulators in this process, and a bridge process
    for each (namespace ``stoptest``), as a hardware run starts them."""
    template = tmp_path / 'template.yaml'
    subprocess.run(
        [ACTIVESURV, 'hardware', 'template', '--out', str(template), '--namespace', 'stoptest'],
        check=True,
        capture_output=True,
    )
    doc = yaml.safe_load(template.read_text())
    emulators = []
    specs = []
    for sensor in load_setup().sensors:
        emu, cfg = camera_controller(sensor, tmp_path / f'tty_{sensor.camera_id}')
        emulators.append(emu)
        doc['cameras'][sensor.camera_id]['stages'] = cfg
        path = tmp_path / f'{sensor.camera_id}.controller.yaml'
        path.write_text(yaml.safe_dump(cfg))
        specs.append(bridge_spec(sensor.camera_id, str(path), home=True))
    emu, cfg = table_controller(tmp_path / 'tty_table')
    emulators.append(emu)
    doc['table']['stages'] = cfg
    path = tmp_path / 'table.controller.yaml'
    path.write_text(yaml.safe_dump(cfg))
    specs.append(bridge_spec('xy_table', str(path), home=True))
    hw = tmp_path / 'hardware.yaml'
    hw.write_text(yaml.safe_dump(doc))
    from dataclasses import replace

    specs = [replace(s, namespace='stoptest') for s in specs]
    try:
        with Launcher(specs, workdir=tmp_path / 'logs') as launcher:
            launcher.wait_alive(1.0)
            yield hw, [s.name for s in specs]
            launcher.check()
    finally:
        for e in emulators:
            e.close()


def test_activesurv_stop_raises_and_releases_the_estop(
    rig_with_bridges: tuple[Path, list[str]],
) -> None:
    hw, _ = rig_with_bridges
    r = subprocess.run(
        [ACTIVESURV, 'stop', '--hardware', str(hw), '--timeout', '30'],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout + r.stderr
    assert 'every bridge confirmed' in r.stdout
    assert 'standing still, goals refused' in r.stdout
    r = subprocess.run(
        [ACTIVESURV, 'stop', '--hardware', str(hw), '--release', '--timeout', '30'],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout + r.stderr
    assert 'accepting goals' in r.stdout


def test_activesurv_stop_names_a_bridge_that_does_not_answer(tmp_path: Path) -> None:
    hw = tmp_path / 'hardware.yaml'
    subprocess.run(
        [ACTIVESURV, 'hardware', 'template', '--out', str(hw), '--namespace', 'nobody_here'],
        check=True,
        capture_output=True,
    )
    r = subprocess.run(
        [ACTIVESURV, 'stop', '--hardware', str(hw), '--timeout', '1'],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 1
    assert 'no confirmation in 1 s from cam1, cam2, cam3, cam4, xy_table' in r.stderr


def _start_run(out: Path) -> tuple[subprocess.Popen[str], Path]:
    log = out.parent / f'{out.name}.log'
    proc = subprocess.Popen(
        [ACTIVESURV, 'experiment', '--set', 'A', '--system', 'fast', '--calibration', 'truth',
         '--out', str(out)],
        stdout=log.open('w'), stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 120.0
    while 'demand 1 of 10 answered' not in log.read_text():  # the graph serves demands
        assert proc.poll() is None, log.read_text()[-3000:]
        assert time.monotonic() < deadline, log.read_text()[-3000:]
        time.sleep(0.2)
    return proc, log


def test_sigterm_stops_a_run_cleanly(tmp_path: Path) -> None:
    """SIGTERM (systemd, docker stop, timeout) is SIGINT: the run exits within 10 s with
    results.json for the demands so far, the bag closed, and no node left running."""
    out = tmp_path / 'run'
    proc, log = _start_run(out)
    assert _processes_mentioning(str(out))  # its nodes run
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    code = proc.wait(30)
    took = time.monotonic() - t0
    text = log.read_text()
    assert code == 128 + signal.SIGTERM, text[-3000:]
    assert took < 10.0, took
    assert 'SIGTERM at simulated time' in text
    assert (out / 'bag' / 'metadata.yaml').is_file()  # closed by the recorder
    doc = json.loads((out / 'results.json').read_text())
    assert 1 <= len(doc['demands']) <= 10
    assert _processes_mentioning(str(out)) == []


def test_no_process_outlives_a_sigkilled_run(tmp_path: Path) -> None:
    """The kernel's parent-death signal stops every node of an orchestrator killed outright
    (and the recorder still closes its bag)."""
    out = tmp_path / 'run'
    proc, _ = _start_run(out)
    nodes = _processes_mentioning(str(out))
    assert len(nodes) >= 5
    proc.kill()
    proc.wait(10)
    deadline = time.monotonic() + 5.0
    while _processes_mentioning(str(out)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _processes_mentioning(str(out)) == []
    assert (out / 'bag' / 'metadata.yaml').is_file()


HANGING_TEARDOWN = """
import rclpy
from rclpy.executors import SingleThreadedExecutor
import activesurv_common.ros.node as node
node.STOP_BOUND = 1.0
rclpy.init()
print('ready', flush=True)
node.spin_until_signal(SingleThreadedExecutor())
while True:  # a teardown that never ends (rclpy's destroy_node once did, holding the GIL)
    pass
"""


def test_a_node_whose_teardown_hangs_is_ended_by_the_alarm() -> None:
    """A node our launcher started (its parent's pid in the environment) that is asked to stop
    and then hangs is ended by the kernel's alarm (``STOP_BOUND``, 1 s here; 8 s in a run,
    beyond the launcher's own SIGKILL at 7 s), not left running: what a SIGKILLed run's
    container once did when the parent-death signal came while its parent still looked alive."""
    env = {**os.environ, 'ACTIVESURV_PARENT_PID': str(os.getpid())}
    proc = subprocess.Popen(
        [sys.executable, '-c', HANGING_TEARDOWN], env=env, stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == 'ready'
        time.sleep(0.3)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(10)
        assert code == -signal.SIGALRM
        assert time.monotonic() - t0 < 5.0
    finally:
        proc.kill()
        proc.wait(5)


SLOW_START = """
import time
from rclpy.node import Node
from activesurv_common.ros.node import run_node

def slow() -> Node:
    print('starting', flush=True)
    time.sleep(1.5)  # a node still starting (compiling kernels, reading files)
    return Node('slow_start')

raise SystemExit(run_node('slow_start', slow, []))
"""


def test_a_node_asked_to_stop_while_starting_stops_cleanly_once_started() -> None:
    """SIGINT while a node is still being built does not kill it mid-start (Python's default
    would: exit -2, nothing flushed): it is remembered, and the node stops as soon as it has
    started, exit 0."""
    proc = subprocess.Popen([sys.executable, '-c', SLOW_START], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == 'starting'
        proc.send_signal(signal.SIGINT)
        assert proc.wait(15) == 0
    finally:
        proc.kill()
        proc.wait(5)
