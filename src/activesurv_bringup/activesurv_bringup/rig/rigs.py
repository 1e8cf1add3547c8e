"""Rigs and calibrations for runs: which hardware the simulator plays, and what the system
believes about it.

* ``--rig RIG.yaml``: the simulated world's true hardware (:mod:`activesurv_sim.rig`); default:
  the paper's nominal rig perturbed with ``--rig-seed`` (independent of the run's seed), as no
  two labs' rigs are alike.
* ``--calibration {CALDIR,nominal,truth}``: what every other node is told. ``truth`` hands the
  system the rig itself (the round-1 world); ``nominal`` the paper's values; a directory is a
  commissioning's result (:mod:`activesurv_common.calibration`). Without the option the rig
  is commissioned first (``activesurv commission``), once per rig, into the cache
  (``~/.cache/activesurv/calibrations/<rig>-<hash>/``, ``ACTIVESURV_CACHE`` moves it) and
  every later command on that rig reuses it.

``activesurv rig nominal --out RIG.yaml`` and ``activesurv rig perturb --in RIG.yaml --seed S
--out RIG2.yaml`` write rig files.
"""

from __future__ import annotations

import argparse
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.files import config_path
from activesurv_common.calibration import Calibration, load_calibration
from activesurv_common.errors import CalibrationError
from activesurv_common.mount import CameraMount
from activesurv_dispatch.sensors import load_setup
from activesurv_sim.rig import (
    Rig,
    RigError,
    load_rig,
    nominal_rig,
    perturb_rig,
    rig_to_dict,
    save_rig,
)

CALIBRATIONS = ('nominal', 'truth')


def nominal_mounts(layout: Path | str | None = None) -> dict[str, CameraMount]:
    """A set-up's mounts by camera id (``layout``: a set-up YAML; default the paper's,
    ``paper_setup.yaml``)."""
    return {s.camera_id: s.mount for s in load_setup(layout).sensors}


def nominal_overhead_pose() -> list[float]:
    try:
        cfg = yaml.safe_load(config_path().read_text())
        return [float(v) for v in cfg['overhead']['pose']]
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise ConfigError(f'experiments.yaml: cannot read overhead.pose: {exc!r}') from exc


def layout_file(layout: str) -> Path | None:
    """The set-up YAML a hardware file's ``geometry.layout`` names (None: ``paper``)."""
    return None if layout == 'paper' else Path(layout)


def nominal(layout: Path | str | None = None) -> Rig:
    """The rig as designed: Table I optics and the mounts of ``layout`` (a set-up YAML, as a
    hardware file's ``geometry.layout`` names it; default the paper's ``paper_setup.yaml``)."""
    return nominal_rig(nominal_mounts(layout), nominal_overhead_pose())


@dataclass(frozen=True)
class RigChoice:
    """A run's rig and calibration, and how they were chosen (for results.json)."""

    rig: Rig
    rig_source: str
    calibration: Calibration
    calibration_source: str
    layout: Path | None = None  # the set-up YAML of the rig as designed (None: the paper's)

    def describe(self) -> dict[str, str | int | None]:
        """What a run record says of this rig (``RunRecord.rig``)."""
        return {
            'rig': self.rig.name,
            'rig_source': self.rig_source,
            'rig_seed': self.rig.seed,
            'calibration': self.calibration_source,
        }


def resolve_rig(path: str | Path | None, seed: int) -> tuple[Rig, str]:
    """The rig of ``--rig`` (a file), or the nominal rig perturbed with ``seed``.

    Raises:
        ConfigError: for an unreadable or malformed rig file.
    """
    try:
        if path is None:
            return perturb_rig(nominal(), seed), f'nominal perturbed with seed {seed}'
        return load_rig(path, nominal_mounts()), str(Path(path).resolve())
    except RigError as exc:
        raise ConfigError(str(exc)) from exc


def resolve_calibration(choice: str, rig: Rig) -> Calibration:
    """``truth`` (the rig itself), ``nominal`` (the paper's values) or a calibration directory.

    Raises:
        ConfigError: for a directory that is not a readable calibration of the rig's cameras.
    """
    if choice == 'truth':
        return rig.truth()
    if choice == 'nominal':
        cal = nominal().truth()
        return Calibration('nominal', cal.cameras, cal.mounts, cal.overhead, cal.overhead_pose)
    try:
        cal = load_calibration(choice, nominal_mounts())
    except CalibrationError as exc:
        raise ConfigError(f'--calibration {choice}: {exc}') from exc
    missing = sorted(set(rig.cameras) - set(cal.cameras))
    if missing:
        raise ConfigError(f'--calibration {choice} has no calibration for {missing}')
    return cal


def default_calibration() -> str | None:
    """``ACTIVESURV_CALIBRATION`` if set (the test suite sets ``truth``), else None: commission."""
    return os.environ.get('ACTIVESURV_CALIBRATION') or None


COMMISSIONING = 5  # procedure version: 2 blurred corners, 3 gamma, 4 linear corners, 5 linear band


def calibration_dir(cache: Path, rig: Rig) -> Path:
    """Where the commissioning of ``rig`` is cached: one per rig content and procedure."""
    content = {**rig_to_dict(rig), 'commissioning': COMMISSIONING}
    if not content['obstacles']:  # (rigs before obstacles existed keep their cache)
        del content['obstacles']
    digest = hashlib.sha256(yaml.safe_dump(content, sort_keys=True).encode())
    return cache / 'calibrations' / f'{rig.name}-{digest.hexdigest()[:10]}'


# -- activesurv rig ---------------------------------------------------------------------------


def run(args: argparse.Namespace) -> Path:
    """Write the rig the command line asks for; returns its path.

    Raises:
        ConfigError: for an existing output file or an unreadable input rig.
    """
    out = Path(args.out)
    if out.exists():
        raise ConfigError(f'{out} exists; choose a new file (a rig is never overwritten)')
    if args.rig_command == 'nominal':
        rig = nominal()
    else:
        try:
            rig = perturb_rig(load_rig(args.source, nominal_mounts()), int(args.seed))
        except RigError as exc:
            raise ConfigError(str(exc)) from exc
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        save_rig(rig, out)
    except RigError as exc:
        raise ConfigError(str(exc)) from exc
    return out
