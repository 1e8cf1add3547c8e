"""Start every node of a run as its own process, watch them, and stop them cleanly.

This stands in for ``ros2 launch`` (not available from PyPI). A :class:`NodeSpec` is what a
launch file's ``Node(...)`` action says: package module, node name, namespace, parameters and
remappings. Each node runs as ``python -m <module> --ros-args ...`` with the same interpreter,
so it needs no console script on PATH and inherits this venv's ROS environment.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import yaml

from activesurv_common.lifetime import PARENT_ENV, child_preexec
from activesurv_launch.errors import NodeDiedError


@dataclass(frozen=True)
class NodeSpec:
    """One node process.

    Attributes:
        name: node name (``__node`` remap) and label in logs.
        module: Python module with a ``main()``, e.g. ``activesurv_fusion.fusion_node``.
        namespace: ROS namespace (``__ns`` remap), '' for the root.
        parameters: ROS parameters, written to a params file.
        remappings: topic remappings ``from -> to``.
        required: a required node that dies fails the whole run.
        host: the host (network namespace) it runs on; '' for this one.
        members: for a container (``module`` is :data:`CONTAINER_MODULE`), the nodes it runs
            in its one process; ``parameters`` and ``remappings`` are then unused.
        nice: how much lower than the orchestrator's its CPU priority is (0: the same):
            background work that must not take the CPU from the critical path of a demand.
    """

    name: str
    module: str
    namespace: str = ''
    parameters: Mapping[str, Any] = field(default_factory=dict)
    remappings: Mapping[str, str] = field(default_factory=dict)
    required: bool = True
    host: str = ''
    members: tuple[NodeSpec, ...] = ()
    nice: int = 0

    @property
    def fqn(self) -> str:
        ns = self.namespace.strip('/')
        return f'/{ns}/{self.name}' if ns else f'/{self.name}'


def process_cpu_seconds(pid: int) -> float | None:
    """User + system CPU seconds of a process (Linux ``/proc``), or None if it is gone."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except (OSError, IndexError):
        return None
    # Fields 14 and 15 of stat (utime, stime), counted after the ')' that ends the name.
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def process_rss_bytes(pid: int) -> int | None:
    """Resident set size of a process (Linux ``/proc``), or None if it is gone."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


CONTAINER_MODULE = 'activesurv_launch.ros.container'


def container(name: str, members: Sequence[NodeSpec], host: str = '', nice: int = 0) -> NodeSpec:
    """A container process running ``members`` (:mod:`activesurv_launch.ros.container`)."""
    return NodeSpec(name, CONTAINER_MODULE, host=host, members=tuple(members), nice=nice)


def members_document(members: Sequence[NodeSpec]) -> dict[str, Any]:
    """The YAML document a container reads its members from."""
    return {
        'members': [
            {
                'name': m.name,
                'module': m.module,
                'namespace': m.namespace,
                'parameters': dict(m.parameters),
                'remappings': dict(m.remappings),
            }
            for m in members
        ]
    }


def node_command(spec: NodeSpec, params_file: Path | None) -> list[str]:
    """The command line that runs ``spec`` (what ``ros2 run`` would execute, plus remaps)."""
    if spec.members:
        if params_file is None:
            raise NodeDiedError(f'container {spec.name} needs its members file')
        return [sys.executable, '-m', CONTAINER_MODULE, str(params_file)]
    cmd = [sys.executable, '-m', spec.module, '--ros-args', '-r', f'__node:={spec.name}']
    if spec.namespace:
        cmd += ['-r', f'__ns:=/{spec.namespace.strip("/")}']
    for src, dst in spec.remappings.items():
        cmd += ['-r', f'{src}:={dst}']
    if params_file is not None:
        cmd += ['--params-file', str(params_file)]
    return cmd


def write_params_file(spec: NodeSpec, directory: Path) -> Path | None:
    """Write the node's parameters as a ROS params YAML keyed by its fully qualified name (for a
    container: its members file)."""
    if spec.members:
        path = directory / f'{spec.name}.members.yaml'
        path.write_text(yaml.safe_dump(members_document(spec.members)))
        return path
    if not spec.parameters:
        return None
    path = directory / f'{spec.fqn.strip("/").replace("/", "__")}.params.yaml'
    path.write_text(yaml.safe_dump({spec.fqn: {'ros__parameters': dict(spec.parameters)}}))
    return path


class NodeProcess:
    """A running node: its process, its log file, and how to stop it."""

    def __init__(
        self,
        spec: NodeSpec,
        workdir: Path,
        env: Mapping[str, str],
        prefix: Sequence[str] = (),
    ) -> None:
        self.spec = spec
        params = write_params_file(spec, workdir)
        self.command = [*prefix, *node_command(spec, params)]
        self.log_path = workdir / f'{spec.fqn.strip("/").replace("/", "__")}.log'
        self._log: IO[bytes] = open(self.log_path, 'ab')  # noqa: SIM115 - closed in stop()
        parent = os.getpid()
        # Its own session (a Ctrl-C in the terminal reaches the orchestrator only, which stops
        # the nodes in order), and SIGTERM from the kernel if the orchestrator dies anyhow.
        self.process = subprocess.Popen(
            self.command,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            env={**env, PARENT_ENV: str(parent)},
            start_new_session=True,
            # only prctl, nice and getppid: fork-safe
            preexec_fn=lambda: child_preexec(parent, spec.nice),
        )
        self.stopped_on_purpose = False

    @property
    def returncode(self) -> int | None:
        return self.process.poll()

    def alive(self) -> bool:
        return self.process.poll() is None

    def tail(self, lines: int = 20) -> str:
        try:
            text = self.log_path.read_text(errors='replace')
        except OSError:
            return ''
        return '\n'.join(text.splitlines()[-lines:])

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Send ``sig`` to the node (for fault injection); the launcher reports it if required."""
        if self.alive():
            os.killpg(self.process.pid, sig)

    def stop(self, timeout: float = 5.0) -> int | None:
        """SIGINT, then SIGTERM, then SIGKILL, like ``ros2 launch`` does on shutdown."""
        self.stopped_on_purpose = True
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0)):
            if not self.alive():
                break
            try:
                os.killpg(self.process.pid, sig)
            except ProcessLookupError:
                break
            try:
                self.process.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        self._log.close()
        return self.process.poll()


class Launcher:
    """Starts node processes, watches them, and stops them all on exit.

    Use as a context manager; :meth:`check` raises :class:`NodeDiedError` when a required node
    has died, with the tail of its log.
    """

    def __init__(
        self,
        specs: Sequence[NodeSpec],
        workdir: Path | None = None,
        env: Mapping[str, str] | None = None,
        hosts: Mapping[str, Sequence[str]] | None = None,
    ) -> None:
        """``hosts`` maps a NodeSpec's host to the command prefix that runs a program there."""
        self.specs = list(specs)
        self.hosts = dict(hosts or {})
        self.workdir = Path(workdir or tempfile.mkdtemp(prefix='activesurv-launch-'))
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.env = dict(os.environ if env is None else env)
        self.processes: dict[str, NodeProcess] = {}

    def __enter__(self) -> Launcher:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        for spec in self.specs:
            self.start_node(spec)

    def run(self, specs: Sequence[NodeSpec]) -> None:
        """Start ``specs`` not started yet (:class:`~activesurv_launch.runner.NodeRunner`)."""
        for spec in specs:
            if spec.fqn not in self.processes:
                self.start_node(spec)

    def start_node(self, spec: NodeSpec) -> NodeProcess:
        if spec.host and spec.host not in self.hosts:
            raise NodeDiedError(f'node {spec.fqn}: unknown host {spec.host!r}')
        proc = NodeProcess(spec, self.workdir, self.env, self.hosts.get(spec.host, ()))
        self.processes[spec.fqn] = proc
        return proc

    def check(self) -> None:
        """Raise if a required node died without being stopped on purpose."""
        for fqn, proc in self.processes.items():
            if proc.spec.required and not proc.alive() and not proc.stopped_on_purpose:
                tail = proc.tail()
                last = next((ln for ln in reversed(tail.splitlines()) if ln.strip()), '')
                raise NodeDiedError(
                    f'node {fqn} died with exit code {proc.returncode}: {last.strip()}\n'
                    f'last log lines:\n{tail}'
                )

    def stop(self) -> dict[str, int | None]:
        """Stop every node, last started first. A Ctrl-C while stopping (a user in a hurry)
        does not leave the rest running: they are stopped quickly, then it is raised."""
        codes: dict[str, int | None] = {}
        hurry = False
        for fqn, proc in reversed(list(self.processes.items())):
            try:
                codes[fqn] = proc.stop(0.5) if hurry else proc.stop()
            except KeyboardInterrupt:
                hurry = True
                proc.stopped_on_purpose = True
                proc.kill()
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.process.wait(2.0)
                codes[fqn] = proc.returncode
        if hurry:
            raise KeyboardInterrupt
        return codes

    def cpu_seconds(self) -> dict[str, float]:
        """CPU seconds (user + system) each running node process has used so far."""
        return {
            fqn: t
            for fqn, proc in self.processes.items()
            if proc.alive() and (t := process_cpu_seconds(proc.process.pid)) is not None
        }

    def rss_bytes(self) -> dict[str, int]:
        """Resident memory of each running node process."""
        return {
            fqn: b
            for fqn, proc in self.processes.items()
            if proc.alive() and (b := process_rss_bytes(proc.process.pid)) is not None
        }

    def wait_alive(self, seconds: float) -> None:
        """Watch the nodes for ``seconds`` (fails fast if one dies while starting)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.check()
            time.sleep(0.05)
