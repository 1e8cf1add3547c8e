"""``activesurv hardware measure-delay``: each camera's exposure delay and stamp jitter, measured.

Every frame is placed in time by its stamp minus ``exposure_delay``; a lab must not have to know
that delay to a few milliseconds. This moves the table back and forth at known speeds in front of
each camera (the dynamic ones at their initial poses, the overhead one over the top board) and
fits the delay that best explains where the frames show the board given where the table
controller reported it (:mod:`activesurv_common.temporal`). The result goes to
``CALDIR/delays.yaml`` (``{camera: {exposure_delay: s, jitter: s, samples: n}}``), which hardware
runs use over the hardware file's guesses.

The board sweep is planned from the calibration (mounts, intrinsics) and the hardware file's
board fixture: the table position that puts the board near the image centre, and a sweep along
the table's x that keeps it well inside the image.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Image, JointState

from activesurv_bringup.errors import ConfigError, NodeDiedError
from activesurv_bringup.rig.commission import (
    Commissioner,
    hardware_commission_specs,
    hardware_triggers,
)
from activesurv_bringup.rig.hardware import hardware_layout
from activesurv_bringup.rig.rigs import nominal, resolve_calibration
from activesurv_common.calibration import Calibration
from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import image_to_gray
from activesurv_common.temporal import DelayFit, TemporalFitError, fit_delay
from activesurv_dispatch.sensors import load_setup
from activesurv_hardware.delays import plan_sweep, write_delays
from activesurv_hardware.hardware_file import Hardware
from activesurv_imaging.calibration import find_corners
from activesurv_launch.launcher import Launcher
from activesurv_recording.bagio import cdr_header
from activesurv_sim.board import BoardFixture
from activesurv_sim.xytable import TABLE_ID, TABLE_JOINTS

Progress = Callable[[str], None]
SPEEDS = (0.02, 0.05)  # m/s of the table's passes


class _Recorder:
    """Every frame of one camera and every table report while recording."""

    def __init__(self, com: Commissioner, image_topics: Mapping[str, tuple[str, str]]) -> None:
        self.on = ''
        self.frames: list[tuple[float, bytes]] = []
        self.table: list[tuple[float, float]] = []
        node = com.node
        node.create_subscription(
            JointState, topics.joint_states(TABLE_ID), self._on_table, qos.STATE
        )
        for cid in com.frames:
            image, _ = image_topics.get(cid, (topics.image(cid), topics.camera_info(cid)))
            node.create_subscription(Image, image, self._on_frame(cid), qos.SENSOR, raw=True)

    def _on_table(self, msg: JointState) -> None:
        if self.on:
            at = dict(zip(msg.name, msg.position, strict=False))
            if TABLE_JOINTS[0] in at:
                t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                self.table.append((t, float(at[TABLE_JOINTS[0]])))

    def _on_frame(self, cid: str) -> Callable[[bytes], None]:
        def keep(data: bytes) -> None:
            if self.on == cid:
                with contextlib.suppress(ValueError):  # not an Image: skipped
                    self.frames.append((cdr_header(data)[0], data))

        return keep


def _board_positions(
    frames: Sequence[tuple[float, bytes]], squares: tuple[int, int]
) -> tuple[list[float], list[Any]]:
    stamps, uv = [], []
    for stamp, data in frames:
        gray = image_to_gray(deserialize_message(data, Image))
        corners = find_corners(gray, squares)
        if corners is not None:
            stamps.append(stamp)
            uv.append(np.asarray(corners, dtype=np.float64).reshape(-1, 2).mean(axis=0))
    return stamps, uv


def measure_camera(
    com: Commissioner,
    rec: _Recorder,
    cid: str,
    plan: tuple[float, float, float],
    squares: tuple[int, int],
    speeds: Sequence[float],
    progress: Progress,
    rate: float = 30.0,
) -> DelayFit:
    """Sweep the table in front of camera ``cid`` and fit its delay (``rate``: Hz a
    software-triggered camera is called at meanwhile)."""
    y, lo, hi = plan
    com.move(TABLE_ID, list(TABLE_JOINTS), np.array([lo, y]), tol=2e-5)
    rec.frames, rec.table, rec.on = [], [], cid
    com.pace(cid, rate)  # a software-triggered camera: called at its frame rate meanwhile
    try:
        for v in speeds:
            for target in (hi, lo):
                com.move(TABLE_ID, [TABLE_JOINTS[0]], np.array([target]), 2e-5, [v])
    finally:
        com.spin(0.3)  # the last frames of the pass
        com.pace(cid, None)
        rec.on = ''
    stamps, uv = _board_positions(rec.frames, squares)
    progress(
        f'{cid}: {len(rec.frames)} frames, board in {len(stamps)}, {len(rec.table)} table '
        f'reports over x {1e3 * lo:.0f}..{1e3 * hi:.0f} mm at y {1e3 * y:.0f} mm'
    )
    if not rec.table:
        raise NodeDiedError('no table reports while sweeping: is the table bridge up?')
    t, x = zip(*rec.table, strict=True)
    try:
        return fit_delay(stamps, np.asarray(uv).reshape(-1, 2), t, x)
    except TemporalFitError as exc:
        raise NodeDiedError(f'{cid}: {exc}') from exc


def run_measure_delay(
    hw: Hardware,
    cal_dir: Path,
    cameras: Sequence[str] | None = None,
    home: bool = False,
    speeds: Sequence[float] = SPEEDS,
    progress: Progress = print,
    startup_timeout: float = 60.0,
) -> dict[str, DelayFit]:
    """Measure the cameras' delays on the rig ``hw`` into ``cal_dir/delays.yaml``.

    Raises:
        ConfigError: without a table, a calibration, or for unknown cameras.
        NodeDiedError: if the graph does not answer or a camera never sees the board.
    """
    if hw.table is None:
        raise ConfigError(f'{hw.path}: measure-delay moves the board on the xy table: none')
    if not (cal_dir / 'commission.json').is_file() and not any(cal_dir.glob('*.yaml')):
        raise ConfigError(
            f'no calibration at {cal_dir}: commission the rig first (activesurv commission '
            f'--live --hardware {hw.path} --out {cal_dir})'
        )
    cal: Calibration = resolve_calibration(str(cal_dir), nominal(hardware_layout(hw)))
    setup = load_setup(hardware_layout(hw), motion='fast')
    chosen = list(cameras) if cameras else list(hw.cameras)
    unknown = sorted(set(chosen) - set(hw.cameras) - {'overhead'})
    if unknown:
        raise ConfigError(f'no cameras {unknown} in {hw.path} (it has {list(hw.cameras)})')
    dynamic = [c for c in chosen if c != 'overhead']
    fixture: BoardFixture = hw.geometry.board
    travel = (hw.geometry.table_x, hw.geometry.table_y)
    plans: dict[str, tuple[float, float, float]] = {}
    joints: dict[str, Any] = {}
    for cid in dynamic:
        sensor, mount = setup.sensor(cid), cal.mounts[cid]
        lims = sensor.limits
        lin = (
            np.linspace(lims[0].min_position, lims[0].max_position, 7)
            if sensor.has_linear
            else [0.0]
        )
        yaw = np.linspace(lims[-1].min_position, lims[-1].max_position, 41)
        qs = [np.array([a, b] if sensor.has_linear else [b]) for a in lin for b in yaw]
        poses = [mount.camera_pose(float(q[0]) if sensor.has_linear else 0.0, q[-1]) for q in qs]
        k, *plan = plan_sweep(cal.cameras[cid], poses, lambda x, y: fixture.pose(x, y).t, travel)
        plans[cid], joints[cid] = (plan[0], plan[1], plan[2]), qs[k]
    _, *over = plan_sweep(
        cal.overhead, [cal.overhead_pose], lambda x, y: fixture.top_pose(x, y).t, travel
    )
    plans['overhead'] = (over[0], over[1], over[2])
    work = cal_dir / 'delays_work'
    work.mkdir(parents=True, exist_ok=True)
    specs, topics_of = hardware_commission_specs(hw, dynamic, work, home)
    launcher = Launcher(specs, workdir=work / 'logs', env=dict(os.environ))
    fits: dict[str, DelayFit] = {}
    with (
        Commissioner(
            setup,
            dynamic,
            image_topics=topics_of,
            namespace=hw.namespace,
            triggers=hardware_triggers(hw),
        ) as com,
        com.hold(launcher, specs, startup_timeout),  # Ctrl-C: the bridges stop their axes
    ):
        rec = _Recorder(com, topics_of)
        for cid in [*dynamic, *(['overhead'] if 'overhead' in chosen or not cameras else [])]:
            started = time.monotonic()
            if cid != 'overhead':
                names = list(setup.sensor(cid).joint_names)
                com.move(cid, names, joints[cid], tol=2e-4)
            squares = fixture.top_squares if cid == 'overhead' else fixture.squares
            cam = hw.overhead if cid == 'overhead' else hw.cameras[cid]
            fit = measure_camera(
                com, rec, cid, plans[cid], squares, speeds, progress, cam.frame_rate
            )
            fits[cid] = fit
            progress(
                f'{cid}: exposure delay {1e3 * fit.delay:.1f} ms, jitter '
                f'{1e3 * fit.jitter:.1f} ms from {fit.samples} frames (fit '
                f'{fit.rms_px:.2f} px rms, {time.monotonic() - started:.0f} s)'
            )
    path = write_delays(cal_dir, fits)
    progress(f'written: {path} (hardware runs with this calibration use it)')
    return fits
