"""Before a hardware run moves anything it lists every axis it will move, from where it stands
(each controller read once, nothing moved) to where it goes, and asks."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
import yaml

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.rig.hardware import confirm_motion, paper_rig, read
from activesurv_bringup.rig.lab import camera_controller, table_controller
from activesurv_dispatch.sensors import load_setup
from activesurv_hardware.hardware_file import template_text

pytestmark = pytest.mark.cross  # bringup's prompt against the stages' emulators


def test_the_prompt_shows_where_each_axis_stands_and_moves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    table, table_cfg = table_controller(tmp_path / 'ttyTABLE')
    cam1, cam1_cfg = camera_controller(
        load_setup(motion='fast').sensor('cam1'), tmp_path / 'ttyCAM1'
    )
    try:
        table.on_line('$X', 0.0)  # unlocked where it stands (0, 0)
        doc = yaml.safe_load(template_text(paper_rig()))
        doc['table']['stages'] = table_cfg
        doc['cameras']['cam1']['stages'] = cam1_cfg
        path = tmp_path / 'rig.yaml'
        path.write_text(yaml.safe_dump(doc))
        hw = read(path)
        said: list[str] = []
        monkeypatch.setattr(sys.stdin, 'isatty', lambda: True)
        with pytest.raises(ConfigError, match='not confirmed'):
            confirm_motion(hw, 'experiment', False, False, ask=lambda _: 'n', say=said.append)
        text = '\n'.join(said)
        assert re.search(r'table_x, table_y: from \(0\.0000, 0\.0000\) m along', text), text
        assert re.search(r'cam1_yaw: from [+-]\d\.\d{4} rad to [+-]\d\.\d{4} rad', text), text
        assert 'cam2: positions not read' in text  # /dev/ttyUSB1 is not here: said, not fatal
        # Read, not moved: nothing but status queries reached the controllers.
        assert not any(line.startswith(b'$J=') for line in table.received)
        assert not any(b'move' in line for line in cam1.received)
    finally:
        table.close()
        cam1.close()


def test_a_second_run_on_a_rig_in_use_is_refused_at_once(tmp_path: Path) -> None:
    import os
    import subprocess

    doc = yaml.safe_load(template_text(paper_rig()))
    ports = {}
    for cid, cam in doc['cameras'].items():
        ports[cid] = tmp_path / f'tty{cid.upper()}'
        cam['stages']['controller']['port'] = str(ports[cid])
    ports['table'] = tmp_path / 'ttyTABLE'
    doc['table']['stages']['controller']['port'] = str(ports['table'])
    for p in ports.values():
        p.touch()  # ports that exist and this user can read and write: the check passes
    path = tmp_path / 'rig.yaml'
    path.write_text(yaml.safe_dump(doc))
    hold = (
        'import sys, time\n'
        'from activesurv_hardware.rig_lock import RigLock\n'
        'lock = RigLock([sys.argv[1]], "activesurv surveil --hardware rig.yaml")\n'
        'print("locked", flush=True)\n'
        'time.sleep(60)\n'
    )
    holder = subprocess.Popen(
        [sys.executable, '-c', hold, str(ports['cam3'])], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None
        assert holder.stdout.readline().strip() == 'locked'
        out = tmp_path / 'run'
        cmd = [os.path.join(os.path.dirname(sys.executable), 'activesurv'), 'experiment']
        cmd += ['--set', 'A', '--system', 'fast', '--hardware', str(path), '--yes']
        cmd += ['--calibration', 'nominal', '--out', str(out)]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    finally:
        holder.kill()
        holder.wait(timeout=10)
    assert done.returncode == 1, done.stdout + done.stderr
    # Refused by the check of the file (its key path), before the run would take the locks.
    assert 'cameras.cam3.stages.controller.port: ' in done.stderr
    assert f'{ports["cam3"]} is in use by pid {holder.pid} (activesurv surveil' in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not out.exists()  # refused before anything was made
