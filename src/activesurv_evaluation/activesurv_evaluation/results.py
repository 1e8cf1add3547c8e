"""Evaluation of a run (paper Section IV-B): per demand instant, visibility and pose errors.

* Position error, eq. 9: the Euclidean distance between the true marker centre (from the xy
  table) and the fused estimate.
* Orientation error, eq. 10: ``acos(n_t . n_e)``, the angle between true and estimated normals.
* Visibility, eq. 2: ``v_f`` of the assigned cameras that really imaged the marker (their
  observation succeeded), with R from the sensor model at the distance and bearing they really
  had to the true target at the demand instant; a camera that did not see the marker contributes
  nothing. This is the "observed visibility" of the paper's Figs. 10-11.

``results.json`` follows the contract in docs/experiments.md: metres and radians.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.geometry import Transform, bearing
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.best_pose import Target, visibility_at_poses
from activesurv_dispatch.sensors import Setup
from activesurv_dispatch.visibility import fused_visibility
from activesurv_evaluation.timing import empty_timing

Array = NDArray[np.float64]


def position_error(estimate: ArrayLike, truth: ArrayLike) -> float:
    """Eq. 9."""
    return float(np.linalg.norm(np.asarray(estimate, float) - np.asarray(truth, float)))


def orientation_error(estimate: ArrayLike, truth: ArrayLike) -> float:
    """Eq. 10 (radians), robust to rounding: both normals are normalised first."""
    a = np.asarray(estimate, float)
    b = np.asarray(truth, float)
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.acos(min(1.0, max(-1.0, c)))


def visibility_from_transforms(
    model: SensorModel, cameras: Sequence[Transform], position: ArrayLike, normal: ArrayLike
) -> float:
    """v_f (eq. 2) of cameras at the given optical-frame poses for a target."""
    c = np.asarray(position, float)
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    Rs = []
    for T in cameras:
        rel = T.t - c
        Rs.append(model.world_covariance(float(np.linalg.norm(rel)), bearing(rel, n), T.R))
    return fused_visibility(Rs)


def observed_visibility(
    setup: Setup,
    model: SensorModel,
    poses: dict[str, Array],
    position: ArrayLike,
    normal: ArrayLike,
) -> float:
    """v_f (eq. 2) of the cameras at ``poses`` (those that imaged the marker), true target:
    the paper's geometric figure of distance and bearing (the sensor model's blur factor is
    left out, as :func:`visibility_from_transforms` leaves it out for a recorded run: the
    evaluation does not know how blurred the real views were)."""
    target = Target(np.asarray(position, float), np.asarray(normal, float))
    sensors = {s.camera_id: s for s in setup.sensors}
    geometric = replace(model, blur_coefficients=np.zeros(6)) if model.models_blur else model
    return visibility_at_poses(
        sensors, geometric, dict(poses), target, setup.marker_radius, only_in_view=False
    )


@dataclass
class DemandRecord:
    """What happened at one demand instant."""

    index: int
    t: float
    true_position: Array
    true_normal: Array
    estimated_position: Array | None = None
    estimated_normal: Array | None = None
    visibility: float = 0.0
    cameras: list[str] = field(default_factory=list)
    faulty: list[str] = field(default_factory=list)
    assigned: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    status: str = 'not_captured'
    reason: str = ''
    latency: float | None = None
    predictions: list[dict[str, Any]] = field(default_factory=list)
    frame_offsets: dict[str, float] = field(default_factory=dict)  # camera: stamp - instant
    object: int = 0  # the object it surveys (0: an experiment's one object)
    # Assigned cameras whose line of sight to the marker was blocked at the instant (from
    # the simulator's truth; None where nothing knows it: hardware runs).
    occluded: list[str] | None = field(default_factory=list)
    # Seconds after the instant of each step (activesurv_evaluation.timing).
    timing: dict[str, Any] = field(default_factory=empty_timing)

    @property
    def position_error(self) -> float | None:
        if self.estimated_position is None or not np.all(np.isfinite(self.true_position)):
            return None
        return position_error(self.estimated_position, self.true_position)

    @property
    def orientation_error(self) -> float | None:
        if self.estimated_normal is None or not np.all(np.isfinite(self.true_normal)):
            return None
        return orientation_error(self.estimated_normal, self.true_normal)

    def to_json(self) -> dict[str, Any]:
        def vec(v: Array | None) -> list[float] | None:  # unknown (None or NaN): null
            return None if v is None or not np.all(np.isfinite(v)) else [float(x) for x in v]

        return {
            'index': self.index,
            't': float(self.t),
            'true_position': vec(self.true_position),
            'estimated_position': vec(self.estimated_position),
            'true_normal': vec(self.true_normal),
            'estimated_normal': vec(self.estimated_normal),
            'position_error': self.position_error,
            'orientation_error': self.orientation_error,
            'visibility': float(self.visibility),
            'cameras': list(self.cameras),
            'faulty': list(self.faulty),
            'assigned': list(self.assigned),
            'missing': list(self.missing),
            'status': self.status,
            'reason': self.reason,
            'latency': self.latency,
            'predictions': self.predictions,
            'frame_offsets': {c: float(v) for c, v in self.frame_offsets.items()},
            'object': self.object,
            'occluded': None if self.occluded is None else list(self.occluded),
            'timing': self.timing,
        }


PREDICTION_LEADS = (2.0, 0.3)  # s before the instant: planning, and the capture request


class PredictionLog:
    """The predicted demand points the dispatcher was given, to compare with the truth.

    Keeps, per demand, every prediction (time made, side-marker position, xy covariance) and
    picks for each lead of :data:`PREDICTION_LEADS` the latest made at least that long before
    the instant.
    """

    def __init__(self) -> None:
        self._log: dict[int, list[tuple[float, Array, Array]]] = {}

    def add(self, made: float, index: int, position: ArrayLike, covariance: ArrayLike) -> None:
        """A prediction of demand ``index`` made at ``made``; ``covariance`` is the 6x6 of
        the demand point (only its xy block is kept)."""
        c = np.asarray(covariance, dtype=np.float64).reshape(6, 6)[:2, :2].copy()
        pos = np.asarray(position, dtype=np.float64).reshape(3).copy()
        entries = self._log.setdefault(int(index), [])
        if entries and entries[-1][0] == made:
            entries[-1] = (made, pos, c)
        else:
            entries.append((made, pos, c))

    def picks(self, index: int, instant: float) -> list[dict[str, Any]]:
        out = []
        for lead in PREDICTION_LEADS:
            made = [e for e in self._log.get(int(index), []) if e[0] <= instant - lead + 1e-9]
            if made:
                t, pos, c = made[-1]
                out.append(
                    {
                        'wanted_lead': lead,
                        'lead': round(instant - t, 4),
                        'position': [float(v) for v in pos],
                        'covariance_xy': [[float(v) for v in row] for row in c],
                    }
                )
        return out


def results_document(
    set_name: str,
    system: str,
    records: Sequence[DemandRecord],
    extra: dict[str, Any] | None = None,
    tracking: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """An experiment's results; ``tracking``: the overhead tracks' figures
    (:func:`activesurv_evaluation.tracking.track_metrics`)."""
    doc: dict[str, Any] = {
        'set': set_name,
        'system': system,
        'demands': [r.to_json() for r in sorted(records, key=lambda r: r.index)],
    }
    if extra:
        doc.update(extra)
    doc['summary'] = {
        'demands': len(records),
        'ok': sum(1 for r in records if r.status == 'ok'),
        'max_objects_at_once': None,
        'id_switches': None,
        'gospa_mean': None,
        **(tracking or {}),
    }
    return doc


def write_results(path: Path, doc: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2) + '\n')


def summary(doc: dict[str, Any]) -> dict[str, float]:
    """Mean visibility, median errors, and how many demands got an estimate."""
    rows = doc['demands']
    # A hardware run without a table controller has no truth: no errors.
    pos = [r['position_error'] for r in rows if r.get('position_error') is not None]
    ori = [r['orientation_error'] for r in rows if r.get('orientation_error') is not None]
    return {
        'mean_visibility': float(np.mean([r['visibility'] for r in rows])) if rows else 0.0,
        'median_position_error': float(np.median(pos)) if pos else math.nan,
        'median_orientation_error': float(np.median(ori)) if ori else math.nan,
        'estimates': float(sum(r.get('estimated_position') is not None for r in rows)),
        'demands': float(len(rows)),
    }


def recovery_demand(b: Sequence[float], a: Sequence[float], within: float = 0.8) -> int:
    """First demand from which curve ``b`` stays at or above ``within`` of curve ``a`` (its
    index; ``len(a)`` if never): when Set B has caught up with Set A."""
    for j in range(len(a)):
        if all(b[i] >= within * a[i] for i in range(j, len(a))):
            return j
    return len(a)
