"""A run's rig and calibration from its command line, commissioning the rig first when no
calibration is given (once per rig, cached next to the runs). Commissioning is handed in
(:data:`Commission`, :func:`activesurv_bringup.rig.commission.run_commission`): its modules
(board views, the response fit, scipy.optimize) took 0.9 s of every run's start, and most runs
use a calibration that exists."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.rig.rigs import (
    CALIBRATIONS,
    RigChoice,
    calibration_dir,
    default_calibration,
    resolve_calibration,
    resolve_rig,
)
from activesurv_common.calibration import Calibration
from activesurv_sim.rig import Rig

# What commissioning a simulated rig takes on a two-core machine (measured: 4-6 min).
COMMISSIONING_ESTIMATE = 'about 5 min on two cores'

Commission = Callable[..., Any]
"""Commissions a rig: ``commission(out, rig, progress=...)``, as ``run_commission``."""


def commissioned(
    cache: Path, rig: Rig, commission: Commission, progress: Callable[[str], None] = print
) -> Path:
    """The rig's calibration in ``cache``, commissioned first if there is none yet.

    A commissioning stopped by SIGINT leaves its partial work in ``<dir>.interrupted`` (never
    read as a calibration); the next run commissions again.
    """
    path = calibration_dir(cache, rig)
    if (path / 'commission.json').is_file():
        progress(f'calibration of {rig.name}: {path} (commissioned before)')
        return path
    if path.exists():  # an unfinished commissioning of another process: leave it alone
        path = path.with_name(f'{path.name}-{int(time.time())}')
    progress(
        f'commissioning {rig.name} into {path} ({COMMISSIONING_ESTIMATE}; once per rig, '
        'later runs reuse it)'
    )
    try:
        commission(path, rig, progress=progress)
    except KeyboardInterrupt:
        kept = path.with_name(f'{path.name}.interrupted-{int(time.time())}')
        if path.exists():
            path.rename(kept)
        progress(f'commissioning interrupted: partial work moved to {kept} (not a calibration)')
        raise
    return path


def choose(
    rig: str | Path | None,
    calibration: str | None,
    rig_seed: int,
    cache: Path | None = None,
    progress: Callable[[str], None] = print,
    commission: Commission | None = None,
) -> RigChoice:
    """A run's rig and calibration from its command line (see the module docstring).

    Args:
        rig: a rig file, or None for the nominal rig perturbed with ``rig_seed``.
        calibration: ``truth``, ``nominal``, a calibration directory, or None: the rig
            commissioned once into ``cache/calibrations/`` (unless ``ACTIVESURV_CALIBRATION``).
        commission: what commissions the rig when it has to be (``run_commission``).
    """
    the_rig, source = resolve_rig(rig, rig_seed)
    cal_choice = calibration or default_calibration()
    if cal_choice is None:
        if cache is None:
            raise ConfigError('commissioning needs a directory for its calibration')
        if commission is None:
            raise ConfigError('no calibration given, and this command does not commission')
        cal_choice = str(commissioned(cache, the_rig, commission, progress))
    cal = with_lens_settings(resolve_calibration(cal_choice, the_rig), the_rig)
    label = cal_choice if cal_choice in CALIBRATIONS else str(Path(cal_choice).resolve())
    return RigChoice(the_rig, source, cal, label)


def with_lens_settings(cal: Calibration, rig: Rig) -> Calibration:
    """``cal`` with each camera's lens settings (f-number, focus distance, focal length) and
    exposure time where it has none: what the lab set its cameras to, known as the settings
    are, not measured (commissioning fits intrinsics and the response; a driver's camera_info
    carries neither)."""
    cameras = {}
    for cid, cam in cal.cameras.items():
        lens = rig.camera(cid).lens if cid in rig.cameras else None
        if lens is not None and not cam.has_lens:
            cam = replace(
                cam,
                f_number=lens.f_number,
                focus_distance=lens.focus_distance,
                focal_length=lens.focal_length,
                exposure_time=cam.exposure_time or lens.exposure_time,
            )
        cameras[cid] = cam
    return replace(cal, cameras=cameras)
