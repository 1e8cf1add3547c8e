"""A camera's measured timing: the sweep that measures it and the file that keeps it.

``activesurv hardware measure-delay`` (:mod:`activesurv_bringup.rig.delays` runs the graph)
sweeps the board on the table in front of each camera: :func:`plan_sweep` picks where, from the
calibration. What it measures goes to ``CALDIR/delays.yaml`` (:func:`write_delays`); hardware
runs take it over the hardware file's guesses (:func:`with_measured_delays`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform
from activesurv_common.temporal import DelayFit
from activesurv_hardware.errors import HardwareFileError
from activesurv_hardware.hardware_file import CameraEntry, Hardware

HALF_SWEEP = 0.04  # m: at most this far either side of the centred position
MARGIN = 0.3  # the board's centre stays this fraction of the image away from its edges
DELAYS_FILE = 'delays.yaml'
"""What ``activesurv hardware measure-delay`` writes into a calibration directory."""


def _project(model: CameraModel, T: Transform, p: Any) -> Any:
    """Pixel of world point ``p`` for a camera at ``T`` (None behind it)."""
    c = T.R.T @ (np.asarray(p, dtype=np.float64) - T.t)
    if c[2] <= 1e-6:
        return None
    return model.project(c[None, :])[0]


def plan_sweep(
    model: CameraModel,
    poses: Sequence[Transform],
    board_centre: Callable[[float, float], Any],
    travel: tuple[tuple[float, float], tuple[float, float]],
) -> tuple[int, float, float, float]:
    """Where to sweep: (index of the camera pose, y, x_low, x_high) that put the board nearest
    the image centre, and the x range along which it stays well inside the image.

    Args:
        model: the camera's intrinsics.
        poses: the camera's candidate poses (``T_world_camera``; one for a static camera).
        board_centre: the board's centre (world) with the carriage at (x, y).
        travel: the table's (x range, y range), m.

    Raises:
        HardwareFileError: if the board is in view at no pose and table position.
    """
    (x0, x1), (y0, y1) = travel
    centre = np.array([model.width / 2.0, model.height / 2.0])
    half = np.array([model.width, model.height]) * (0.5 - MARGIN)
    grid = [
        (float(x), float(y)) for y in np.linspace(y0, y1, 21) for x in np.linspace(x0, x1, 101)
    ]
    points = np.array([board_centre(x, y) for x, y in grid], dtype=np.float64)
    best: tuple[float, int, int] | None = None
    for k, T in enumerate(poses):
        c = (points - T.t) @ T.R
        front = np.flatnonzero(c[:, 2] > 1e-6)
        if front.size == 0:
            continue
        d = np.linalg.norm(model.project(c[front]) - centre, axis=1)
        i = int(np.argmin(d))
        if best is None or d[i] < best[0]:
            best = (float(d[i]), k, int(front[i]))

    def inside(k: int, x: float, y: float) -> bool:
        px = _project(model, poses[k], board_centre(x, y))
        return px is not None and bool(np.all(np.abs(px - centre) <= half))

    if best is None or not inside(best[1], *grid[best[2]]):
        raise HardwareFileError(
            'the board is in view at no camera pose and table position (check the layout)'
        )
    k = best[1]
    xc, yc = grid[best[2]]
    lo = hi = xc
    step = 0.001
    while lo - step >= x0 and xc - (lo - step) <= HALF_SWEEP and inside(k, lo - step, yc):
        lo -= step
    while hi + step <= x1 and (hi + step) - xc <= HALF_SWEEP and inside(k, hi + step, yc):
        hi += step
    if hi - lo < 0.01:
        raise HardwareFileError(f'the board stays in view over {1e3 * (hi - lo):.0f} mm only')
    return k, yc, lo, hi


def write_delays(cal_dir: Path, fits: Mapping[str, DelayFit]) -> Path:
    """``CALDIR/delays.yaml``: the measured delays (merged with earlier cameras' there)."""
    path = cal_dir / DELAYS_FILE
    doc = read_delays(cal_dir)
    full: dict[str, Any] = {c: dict(v) for c, v in doc.items()}
    for cid, f in fits.items():
        full[cid] = {
            'exposure_delay': round(f.delay, 6),
            'jitter': round(f.jitter, 6),
            'samples': int(f.samples),
            'rms_px': round(f.rms_px, 4),
        }
    cal_dir.mkdir(parents=True, exist_ok=True)
    path.write_text(
        '# activesurv hardware measure-delay: s from exposure to frame stamp, per camera\n'
        + yaml.safe_dump(full, sort_keys=True)
    )
    return path


def read_delays(cal_dir: Path) -> dict[str, dict[str, float]]:
    """The measured delays of a calibration directory ({} when none were measured).

    Raises:
        HardwareFileError: for a malformed file.
    """
    path = cal_dir / DELAYS_FILE
    if not path.is_file():
        return {}
    try:
        doc = yaml.safe_load(path.read_text()) or {}
        out = {str(c): {k: float(v) for k, v in e.items()} for c, e in doc.items()}
    except (yaml.YAMLError, AttributeError, TypeError, ValueError) as exc:
        raise HardwareFileError(f'{path}: not a delays file ({exc})') from exc
    for cid, e in out.items():
        d = e.get('exposure_delay', math.nan)
        if not (math.isfinite(d) and -1.0 <= d <= 1.0):
            raise HardwareFileError(
                f'{path}: {cid}.exposure_delay must be a finite -1..1 s, got {d}'
            )
    return out


def with_measured_delays(
    hw: Hardware, cal_dir: Path | None, say: Callable[[str], None] = print
) -> Hardware:
    """The rig with the exposure delays ``activesurv hardware measure-delay`` measured into
    ``cal_dir`` (the calibration a run uses) in place of the hardware file's guesses.

    Raises:
        ConfigError: for a malformed delays file.
    """
    if cal_dir is None:
        return hw
    measured = read_delays(cal_dir)
    if not measured:
        return hw
    told = []

    def entry(cam: CameraEntry) -> CameraEntry:
        m = measured.get(cam.camera_id)
        if m is None:
            return cam
        told.append(
            f'{cam.camera_id} {1e3 * m["exposure_delay"]:.1f} ms (file '
            f'{1e3 * cam.exposure_delay:.1f})'
        )
        return replace(cam, exposure_delay=float(m['exposure_delay']))

    out = replace(
        hw,
        cameras={c: entry(e) for c, e in hw.cameras.items()},
        overhead=entry(hw.overhead),
    )
    say(f'measured exposure delays ({cal_dir / DELAYS_FILE}): {", ".join(told)}')
    return out
