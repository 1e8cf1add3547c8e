"""One entry point for every node's console script: start, spin, stop, one-line start-up errors.

::

    def main(args: list[str] | None = None) -> int:
        return run_node('fusion', FusionNode, args, on_stop=FusionNode.flush)

A node that cannot start (a bad parameter, a missing or malformed configuration file) prints
``<name>: error: <reason>`` on stderr and the process exits with status 1, without a traceback.
SIGINT, SIGTERM and SIGHUP stop the spin, and so does the death of the orchestrator that
started the node; ``on_stop`` then runs while the node still has its publishers
(fusion answers its open demands, the recorder closes its bag), and the context ends.

Nodes spin on rclpy's ``EventsExecutor`` (C++, no wait set rebuilt on every wake-up: the
single-threaded executor spent most of an idle node's CPU there); ``ACTIVESURV_EXECUTOR=single``
selects rclpy's ``SingleThreadedExecutor`` instead.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable, Sequence
from types import FrameType
from typing import Any, NoReturn, TypeVar

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from activesurv_common.errors import CommonError
from activesurv_common.lifetime import PARENT_ENV, STOP_SIGNALS, orphaned
from activesurv_common.ros import callback_cpu, fast_logging

N = TypeVar('N', bound=Node)

STARTUP_ERRORS: tuple[type[Exception], ...] = (
    ParameterException,
    CommonError,
    ValueError,
    OSError,
    KeyError,
)
"""What a node's constructor raises for bad parameters or configuration files."""


def one_line(exc: BaseException) -> str:
    return ' '.join(str(exc).split()) or type(exc).__name__


EXECUTORS = ('events', 'single')


def make_executor() -> Executor:
    """The executor our processes spin (``ACTIVESURV_EXECUTOR``: events, the default, or single).

    Raises:
        ValueError: for another value of ``ACTIVESURV_EXECUTOR``.
    """
    kind = os.environ.get('ACTIVESURV_EXECUTOR', 'events') or 'events'
    if kind not in EXECUTORS:
        raise ValueError(f'ACTIVESURV_EXECUTOR must be one of {EXECUTORS}, got {kind!r}')
    if kind == 'events':
        from rclpy.experimental import EventsExecutor

        return EventsExecutor()
    return SingleThreadedExecutor()


ORPHAN_GRACE = 3.0
"""s a node whose orchestrator is gone has to stop (its on-stop work included) before the
kernel ends it: nobody else is left to escalate."""

STOP_BOUND = 8.0
"""s a node started by our launcher may take to stop once asked while its orchestrator lives:
beyond the launcher's own escalation (SIGINT, 5 s, SIGTERM, 2 s, SIGKILL), so it never cuts a
stop short; it ends a node whose teardown hangs after its orchestrator died unseen."""


class StopRequest:
    """Whether SIGINT, SIGTERM or SIGHUP has come since it was made (it installs their
    handlers): made before a node is built, a stop asked while the node is still starting
    (importing, compiling, reading its files) ends it cleanly once it has started, where
    Python's default SIGINT would kill it mid-start. Before it is made, the SIGINT of a process
    our launcher started is held (:func:`~activesurv_common.lifetime.child_preexec`)."""

    def __init__(self) -> None:
        self.requested = False
        for sig in STOP_SIGNALS:
            signal.signal(sig, self._on_signal)
        # A SIGINT the launcher held while this process started is delivered now, to the handler.
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True
        if orphaned():
            _arm_orphan_alarm()


def spin_until_signal(executor: Executor, stop: StopRequest | None = None) -> None:
    """Spin until SIGINT, SIGTERM, SIGHUP (since ``stop`` was made; default: from now), an
    external shutdown of the context, or the death of the process that started this one
    (:func:`~activesurv_common.lifetime.orphaned`).

    A node left without its orchestrator (it was SIGKILLed) stops as on SIGTERM, and an alarm
    ends the process :data:`ORPHAN_GRACE` seconds later whatever its on-stop work is doing.
    """
    stop = StopRequest() if stop is None else stop
    watched = PARENT_ENV in os.environ
    # The parent's pid read once: the environment's lookup and decoding on every wake-up
    # was 4 % of the core process's CPU.
    parent = os.environ.get(PARENT_ENV, '')
    parent_pid = int(parent) if parent.isdigit() else -1
    try:
        while rclpy.ok() and not stop.requested:
            executor.spin_once(timeout_sec=0.1)
            if parent_pid >= 0 and os.getppid() != parent_pid:
                stop.requested = True
                _arm_orphan_alarm()
    except ExternalShutdownException:
        pass
    if watched:
        # Bound the teardown that follows in every case: it can hang (a clean clone once saw
        # an orphaned container spin in rclpy's destroy_node for minutes, holding the GIL, so
        # no Python handler or thread could act), and the parent-death signal can come while
        # the parent still looks alive (the kernel sends it when the thread that started this
        # process exits, before the rest of the parent's threads), so the handler's own look
        # may have missed the orphaning. The kernel's alarm ends the process either way.
        _arm_alarm(ORPHAN_GRACE if orphaned() else STOP_BOUND)


def _arm_orphan_alarm() -> None:
    _arm_alarm(ORPHAN_GRACE)


def _arm_alarm(seconds: float) -> None:
    signal.signal(signal.SIGALRM, signal.SIG_DFL)  # the default action ends the process
    signal.alarm(max(1, round(seconds)))


def run_node(
    name: str,
    factory: Callable[[], N],
    args: list[str] | None = None,
    on_stop: Callable[[N], object] | None = None,
    errors: tuple[type[Exception], ...] = (),
) -> int:
    """Construct ``factory()`` and spin it until SIGINT/SIGTERM or an external shutdown.

    Args:
        name: the executable's name, for error lines.
        factory: builds the node (usually its class).
        args: command-line arguments (rclpy reads ``--ros-args``).
        on_stop: runs after the spin, before the node is destroyed.
        errors: start-up errors of the node's package, in addition to :data:`STARTUP_ERRORS`.

    Returns:
        The exit status: 0 after a clean stop (or after ``--help``), 1 if the node could not
        start.
    """
    argv = sys.argv[1:] if args is None else args
    mine = argv[: argv.index('--ros-args')] if '--ros-args' in argv else argv
    if '-h' in mine or '--help' in mine:
        print(help_text(name, factory))
        return 0
    stop = StopRequest()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    fast_logging.install()
    callback_cpu.install()  # ACTIVESURV_CALLBACK_CPU: a diagnostic, off by default
    try:
        node = factory()
    except (*STARTUP_ERRORS, *errors) as exc:
        print(f'{name}: error: {one_line(exc)}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    try:
        executor = make_executor()
    except ValueError as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()
        return 1
    executor.add_node(node)
    try:
        spin_until_signal(executor, stop)
    finally:
        if on_stop is not None:
            on_stop(node)
        executor.shutdown()
        callback_cpu.write(node.get_fully_qualified_name())
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def help_text(name: str, factory: Callable[..., Any]) -> str:
    """``--help`` of a node's console script: what it is, how to set its parameters, and each
    parameter with its default (from the ``PARAMS`` its module declares)."""
    module = sys.modules.get(getattr(factory, '__module__', ''), None)
    doc = (factory.__doc__ or getattr(module, '__doc__', None) or '').strip().split('\n\n')[0]
    params: Sequence[Any] = getattr(module, 'PARAMS', ())
    lines = [
        f'usage: {name} [--ros-args [-r __node:=NAME] [-r __ns:=/NS] [-p NAME:=VALUE ...] '
        '[--params-file FILE.yaml]]',
        '',
        ' '.join(doc.split()),
    ]
    if params:
        lines += ['', 'parameters:']
        for p in params:
            plain = isinstance(p.default, (bool, int, float, str, list))
            default = p.default if plain else 'unset'
            lines.append(f'  {p.name} (default: {default!r}): {p.description}')
    return '\n'.join(lines)


def exit_now(code: int) -> NoReturn:
    """Leave the process at once once ``main`` is done: its nodes destroyed, the bag closed,
    rclpy shut down; the DDS participant is destroyed here (the others hear it leave, its
    shared memory is released). What is skipped is the interpreter's own teardown of numpy,
    OpenCV and the node objects: 0.2-0.3 s a process, 2 s of a signalled run's exit. Buffered
    Python files not closed by ``main`` would lose their tail: a node's ``main`` closes its own."""
    with contextlib.suppress(Exception):
        rclpy.utilities.get_default_context().destroy()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
