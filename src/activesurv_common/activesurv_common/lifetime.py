"""No process outlives the run that started it, whatever signal ends the run.

Two halves:

* :func:`child_preexec` runs in each node process between ``fork`` and ``exec`` (Linux): it
  asks the kernel to send the child SIGTERM when its parent dies (``PR_SET_PDEATHSIG``), so a
  SIGKILLed orchestrator still stops every node it started (a stage bridge then stops its
  axes, the recorder closes its bag). The signal survives ``exec`` of a non-setuid program, so
  it also holds through ``ip netns exec``. It also blocks SIGINT, which stays pending until
  the node has installed its own stop handlers (:class:`~activesurv_common.ros.node.StopRequest`
  unblocks it): a Ctrl-C or a launcher's stop that comes while the node still imports its
  modules then ends it cleanly once it has started, where Python's default handler would kill
  it mid-import (exit status -2). SIGTERM is left as it was: the launcher's escalation and the
  parent-death signal still end a node that hangs while it starts.
* :class:`StopSignals` is the orchestrator's side: SIGINT, SIGTERM and SIGHUP (what Ctrl-C,
  ``systemd``, ``docker stop``, ``timeout`` and a closed terminal send) all ask for the same
  clean stop: open demands are answered and the bag is closed. A second signal while stopping
  raises :class:`KeyboardInterrupt` (a user in a hurry): the nodes are then stopped quickly.

The variable :data:`PARENT_ENV` tells a node which process started it; the node's own watch
(:func:`orphaned`) covers the one gap of the parent-death signal (a parent that died between
``fork`` and the ``prctl`` call).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
from types import FrameType, TracebackType
from typing import Any

PARENT_ENV = 'ACTIVESURV_PARENT_PID'
"""Set by the launcher in each node's environment: the pid of the process that started it."""

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that ask a run to stop cleanly."""

HELD_WHILE_STARTING = (signal.SIGINT,)
"""The signals a node process started by our launcher holds (blocked, pending) until its stop
handlers are in place."""

_PR_SET_PDEATHSIG = 1


def _libc() -> Any:
    name = ctypes.util.find_library('c') or 'libc.so.6'
    return ctypes.CDLL(name, use_errno=True)


def set_parent_death_signal(sig: int = signal.SIGTERM) -> bool:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux only).

    Returns:
        Whether the request was accepted (False on other systems).
    """
    if not sys.platform.startswith('linux'):
        return False
    try:
        return int(_libc().prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


def child_preexec(parent_pid: int, nice: int = 0) -> None:
    """``preexec_fn`` of a node process: die with the parent, even if it is already gone; hold
    SIGINT until the node can stop cleanly; ``nice``: lower its CPU priority by that much
    (background work)."""
    set_parent_death_signal(signal.SIGTERM)
    signal.pthread_sigmask(signal.SIG_BLOCK, HELD_WHILE_STARTING)  # survives exec
    if nice > 0:
        os.nice(nice)  # within its own session only, where kernels group sessions (autogroups)
    if os.getppid() != parent_pid:  # the parent died before the prctl above
        os.kill(os.getpid(), signal.SIGTERM)


def orphaned(environ: dict[str, str] | None = None) -> bool:
    """Whether the process that started this one (``ACTIVESURV_PARENT_PID``) is gone."""
    env = os.environ if environ is None else environ
    parent = env.get(PARENT_ENV, '')
    if not parent.isdigit():
        return False
    return os.getppid() != int(parent)


class StopSignals:
    """SIGINT, SIGTERM and SIGHUP set :attr:`requested` instead of killing the orchestrator.

    Use as a context manager around a run; the previous handlers come back on exit. The first
    signal asks for a clean stop; a second one raises :class:`KeyboardInterrupt`.
    """

    def __init__(self) -> None:
        self.requested: str = ''
        self._old: dict[int, Any] = {}

    def __enter__(self) -> StopSignals:
        for sig in STOP_SIGNALS:
            try:
                self._old[sig] = signal.signal(sig, self._on_signal)
            except ValueError:  # not the main thread: signals stay where they are
                break
        return self

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = signal.Signals(signum).name

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        for sig, handler in self._old.items():
            signal.signal(sig, handler)
        self._old.clear()


class StopRequested(Exception):  # noqa: N818 - a request, not an error
    """A run stopped early on a signal; what it recorded is complete and closed.

    Attributes:
        signal_name: ``SIGINT``, ``SIGTERM`` or ``SIGHUP``.
    """

    def __init__(self, signal_name: str) -> None:
        super().__init__(f'stopped by {signal_name}')
        self.signal_name = signal_name

    @property
    def exit_status(self) -> int:
        """The shell's convention for a process ended by the signal (128 + its number)."""
        return 128 + int(signal.Signals[self.signal_name])
