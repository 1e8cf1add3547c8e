"""A node container: several of our nodes in one process, as ``ros2 component`` containers do.

``python -m activesurv_launch.ros.container MEMBERS.yaml`` constructs every node listed
in the file (the same node classes the console scripts run, with their names, namespaces,
remappings and parameters) and spins them on one executor (rclpy's ``EventsExecutor``, see
:func:`activesurv_common.ros.node.make_executor`). One Python process per group
of nodes instead of one per node: the interpreter, the DDS participant and the /clock
subscription are paid once, not 19 times, and messages between the members stay inside the
process (:mod:`activesurv_common.ros.local_topics`: a camera's frames reach its imager as a
Python call, before they go over DDS). Every node stays runnable alone with its console
script; graph mode groups them into containers per host (see
:mod:`activesurv_bringup.experiments.graph`).

The members file::

    members:
      - {name: fusion, module: activesurv_fusion.fusion_node, namespace: '',
         parameters: {use_sim_time: true, ...}, remappings: {}}

SIGINT/SIGTERM end the spin; then nodes with a ``flush()`` (fusion answers its open demands)
flush, the executor runs a little longer so those answers leave (only if one sent any), nodes
with a ``close()`` (the recorder) close, and all are destroyed. A member that cannot start
stops the container with ``<member>: error: <reason>`` and exit status 1, as its console script
would.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import rclpy
import yaml
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

from activesurv_common.ros import callback_cpu, fast_logging, local_topics
from activesurv_common.ros.node import (
    StopRequest,
    exit_now,
    make_executor,
    one_line,
    spin_until_signal,
)
from activesurv_common.yamlio import load_yaml
from activesurv_launch.launcher import NodeSpec
from activesurv_launch.ros.compose import build_node, share_clock


def load_members(path: Path) -> list[NodeSpec]:
    """The members of a container file.

    Raises:
        ValueError: if the file is not a members document.
    """
    doc = load_yaml(path.read_text())
    if not isinstance(doc, dict) or not isinstance(doc.get('members'), list):
        raise ValueError(f'{path}: expected a mapping with a list of members')
    out = []
    for m in doc['members']:
        if not isinstance(m, dict) or 'name' not in m or 'module' not in m:
            raise ValueError(f'{path}: every member needs a name and a module: {m!r}')
        out.append(
            NodeSpec(
                str(m['name']),
                str(m['module']),
                str(m.get('namespace', '')),
                dict(m.get('parameters') or {}),
                dict(m.get('remappings') or {}),
            )
        )
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 1 or args[0].startswith('-'):
        print('usage: python -m activesurv_launch.ros.container MEMBERS.yaml', file=sys.stderr)
        return 2
    try:
        members = load_members(Path(args[0]))
    except (OSError, ValueError, yaml.YAMLError) as exc:
        print(f'container: error: {one_line(exc)}', file=sys.stderr)
        return 1
    stop = StopRequest()  # a stop asked while the members start ends the container once started
    rclpy.init(args=args[1:], signal_handler_options=SignalHandlerOptions.NO)
    fast_logging.install()
    callback_cpu.install()  # ACTIVESURV_CALLBACK_CPU: a diagnostic, off by default
    local_topics.enable()  # one thread spins all members: in-process delivery is safe
    nodes: list[Any] = []
    for m in members:
        try:
            nodes.append(build_node(m))
        # A member of any package: its own start-up errors end the container with their reason.
        except Exception as exc:
            print(f'{m.name}: error: {one_line(exc)}', file=sys.stderr)
            for n in nodes:
                n.destroy_node()
            rclpy.try_shutdown()
            return 1
    share_clock(nodes)
    try:
        executor = make_executor()
    except ValueError as exc:
        print(f'container: error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    for n in nodes:
        executor.add_node(n)
    try:
        spin_until_signal(executor, stop)
        flushed = False
        for n in nodes:
            flush = getattr(n, 'flush', None)
            if callable(flush):
                sent = flush()  # fusion answers its open demands while the recorder listens
                # The executor runs on only for what went out (how many: None if unknown): an
                # idle camera leaves at once (0.3 s each of a signalled run's exit).
                flushed = flushed or sent is None or sent > 0
        end = time.monotonic() + (0.3 if flushed else 0.0)
        while rclpy.ok() and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
    except ExternalShutdownException:
        pass
    finally:
        for n in nodes:
            close = getattr(n, 'close', None)
            if callable(close):
                close()  # the recorder closes its bag
        executor.shutdown()
        callback_cpu.write('/' + Path(args[0]).name.removesuffix('.members.yaml'))
        for n in reversed(nodes):
            n.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    exit_now(main())
