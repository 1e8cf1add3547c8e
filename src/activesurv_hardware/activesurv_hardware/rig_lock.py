"""One run at a time on a rig: an advisory lock per controller port.

Every command that moves a rig (``experiment`` / ``surveil --hardware``, ``commission --live``,
``hardware measure-delay``) takes an exclusive ``flock`` on a lock file per serial port before it
opens a port, and holds it for its life: a second run on the same controllers is refused in a
second, naming the run that holds them, instead of two bridges writing to one controller. The
kernel drops the lock with the process, however it ends (SIGKILL included): no stale locks.

The lock files live in ``ACTIVESURV_LOCK_DIR``, else ``/run/lock`` (world-writable on Linux
distributions, like the serial tools' own lock files), else the temporary directory; a file is
named after the port's real path (a ``/dev/serial/by-id`` link and its ``/dev/ttyUSB0`` are one
port). Ports shared by one run (a Zaber daisy chain) are locked once.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path

from activesurv_hardware.errors import HardwareError

LOCK_DIR_ENV = 'ACTIVESURV_LOCK_DIR'


class RigBusyError(HardwareError):
    """A controller port is held by another run (``holder``: who, as its lock file says)."""

    def __init__(self, message: str, holder: str = '') -> None:
        super().__init__(message)
        self.holder = holder


def lock_dir() -> Path:
    """Where the lock files are kept (see the module doc)."""
    chosen = os.environ.get(LOCK_DIR_ENV)
    if chosen:
        return Path(chosen)
    run_lock = Path('/run/lock')
    if run_lock.is_dir() and os.access(run_lock, os.W_OK | os.X_OK):
        return run_lock
    return Path(tempfile.gettempdir())


def lock_path(port: str, directory: Path | None = None) -> Path:
    """The lock file of ``port`` (by its real path)."""
    real = os.path.realpath(port)
    name = 'activesurv-' + real.strip('/').replace('/', '_') + '.lock'
    return (directory or lock_dir()) / name


class RigLock:
    """Exclusive locks on a rig's controller ports, held until :meth:`release` or exit."""

    def __init__(self, ports: Iterable[str], what: str, directory: Path | None = None) -> None:
        """Lock every port of ``ports`` for ``what`` (e.g. ``activesurv surveil``).

        Raises:
            RigBusyError: if another process holds one of them (nothing stays locked then).
        """
        self._fds: list[int] = []
        where = directory or lock_dir()
        seen = set()
        try:
            for port in ports:
                path = lock_path(port, where)
                if path in seen:
                    continue  # a daisy chain: one port, one lock
                seen.add(path)
                self._fds.append(_take(path, port, what))
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        for fd in self._fds:
            with contextlib.suppress(OSError):
                os.close(fd)  # closing the descriptor drops its flock
        self._fds.clear()

    def __enter__(self) -> RigLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def holder(port: str, directory: Path | None = None) -> str | None:
    """Who holds ``port`` now (``pid N (command, since HH:MM:SS)``), or None when it is free.

    Only the lock file is touched: the port itself is not opened (opening a serial port can
    reset the board behind it, as an Arduino running GRBL does).
    """
    try:
        RigLock([port], 'activesurv hardware check', directory).release()
    except RigBusyError as exc:
        return exc.holder or str(exc)
    return None


def _take(path: Path, port: str, what: str) -> int:
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise RigBusyError(f'cannot open the lock file of {port} ({path}): {exc}') from exc
    with contextlib.suppress(OSError):
        os.fchmod(fd, 0o666)  # another user's run must be able to take it later
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        who = os.pread(fd, 512, 0).decode(errors='replace').strip() or 'another process'
        os.close(fd)
        raise RigBusyError(
            f'the rig is in use: {port} is held by {who}; wait for that run to end or stop '
            'it (Ctrl-C in its terminal; activesurv stop --hardware FILE stops its stages)',
            who,
        ) from None
    os.ftruncate(fd, 0)
    stamp = time.strftime('%H:%M:%S')
    os.pwrite(fd, f'pid {os.getpid()} ({what}, since {stamp})\n'.encode(), 0)
    return fd
