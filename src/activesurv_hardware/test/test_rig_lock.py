"""One run at a time on a rig: a second process cannot take a port another one holds."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from activesurv_hardware.rig_lock import RigBusyError, RigLock, holder, lock_path

HOLD = (
    'import sys, time\n'
    'from pathlib import Path\n'
    'from activesurv_hardware.rig_lock import RigLock\n'
    'lock = RigLock(sys.argv[2:], "activesurv surveil --hardware lab.yaml", Path(sys.argv[1]))\n'
    'print("locked", flush=True)\n'
    'time.sleep(60)\n'
)


def _holder(tmp_path: Path, *ports: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, '-c', HOLD, str(tmp_path / 'locks'), *ports],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == 'locked'
    return proc


def test_a_second_run_is_refused_and_a_killed_one_leaves_no_lock(tmp_path: Path) -> None:
    locks = tmp_path / 'locks'
    table, cam = tmp_path / 'ttyTABLE', tmp_path / 'ttyCAM1'
    table.touch()
    cam.touch()
    link = tmp_path / 'by-id-table'
    link.symlink_to(table)
    proc = _holder(tmp_path, str(table))
    try:
        # The same port by another name (a /dev/serial/by-id link) is the same port.
        with pytest.raises(RigBusyError, match=rf'held by pid {proc.pid} \(activesurv surveil'):
            RigLock([str(cam), str(link)], 'activesurv experiment', locks)
        # Nothing stayed locked by the refused run: cam1's port is free.
        with RigLock([str(cam)], 'activesurv commission', locks):
            pass
        assert holder(str(cam), locks) is None
        held = holder(str(table), locks)
        assert held is not None
        assert held.startswith(f'pid {proc.pid} (activesurv surveil --hardware lab.yaml, since ')
    finally:
        os.kill(proc.pid, signal.SIGKILL)  # the kernel drops a killed process's locks
        proc.wait(timeout=10)
    assert holder(str(table), locks) is None
    with RigLock([str(link), str(cam), str(cam)], 'activesurv experiment', locks):
        assert lock_path(str(link), locks) == lock_path(str(table), locks)
        text = lock_path(str(table), locks).read_text()
        assert text.startswith(f'pid {os.getpid()} (activesurv experiment, since ')
