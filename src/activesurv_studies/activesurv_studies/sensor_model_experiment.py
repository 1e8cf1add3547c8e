"""Two-factorial sensor-model experiment (paper Appendix A) on the simulated camera.

For every cell of a grid of distances d and bearings theta, the marker is rendered ``repetitions``
times from a camera placed at distance d with the marker normal at bearing theta to the line of
sight (random azimuth about the normal, random aim within a few millimetres, fresh image noise),
and measured with the full imaging pipeline. The errors in x, y, z, n_x, n_y, n_z (camera optical
frame) give six variances per cell; a quadratic response surface in (d, theta) is fitted to the
log of each and written to YAML with the raw cell data; a Fig.-16-style plot shows them.

A blur study (:func:`run_blur_study`, :func:`fit_blur`) then renders cells at two distances and
two bearings through a defocus blur of 2, 4 and 8 px as well and fits the model's third factor
(:attr:`activesurv_common.sensor_model.SensorModel.blur_coefficients`).

Command line::

    activesurv_sensor_model --out DIR [--distances 0.40,0.50,0.60,0.70,0.80]
        [--bearings-deg 0,10,20,30,40,50,60,70] [--repetitions 20] [--seed 1] [--jobs N]
        [--blurs 0,2,4,8]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from activesurv_common.camera_model import CameraModel, dynamic_camera
from activesurv_common.errors import SensorModelError
from activesurv_common.geometry import rotation_between, unit
from activesurv_common.sensor_model import (
    N_TERMS,
    VARIABLES,
    SensorModel,
    blur_term,
    design_row,
)
from activesurv_imaging.marker_pose import MeasurementStatus, measure_marker
from activesurv_sim.frame_optics import IDEAL_OPTICS, FrameOptics
from activesurv_sim.render import (
    Plate,
    Scene,
    SensorNoise,
    look_at,
    render,
)

Array = NDArray[np.float64]
MARKER = np.array([0.0, 0.0, 0.0])
NORMAL = np.array([0.0, -1.0, 0.0])


@dataclass(frozen=True)
class CellResult:
    distance: float
    bearing: float
    variances: Array  # (6,), NaN when too few trials succeeded
    successes: int
    failures: int
    blur: float = 0.0  # px: the defocus blur the cell was rendered with
    edge_blur: float = math.nan  # px: the median blur the detector saw on the edges


def _cell(
    args: tuple[float, float, int, int, float, CameraModel, SensorNoise]
    | tuple[float, float, int, int, float, CameraModel, SensorNoise, float],
) -> CellResult:
    d, theta, reps, seed, radius, camera, noise = args[:7]
    blur = float(args[7]) if len(args) > 7 else 0.0
    optics = FrameOptics(defocus_sigma=blur) if blur > 0.0 else IDEAL_OPTICS
    rng = np.random.default_rng(seed)
    errors = []
    edge_blurs = []
    failures = 0
    for _ in range(reps):
        az = rng.uniform(-math.pi, math.pi)
        # Direction from the marker to the camera: the normal tilted by theta towards azimuth az.
        perp = unit(np.cross(NORMAL, [math.cos(az), 0.0, math.sin(az)]))
        view = math.cos(theta) * NORMAL + math.sin(theta) * np.cross(perp, NORMAL)
        eye = MARKER + d * unit(view)
        aim = MARKER + rng.normal(0.0, 0.003, 3)
        up = (0.0, 0.0, 1.0) if abs(unit(view)[2]) < 0.95 else (1.0, 0.0, 0.0)
        T = look_at(eye, aim, up)
        scene = Scene((Plate.disc(MARKER, NORMAL, radius),))
        img = render(camera, T, scene, noise, rng, optics)
        Tinv = T.inverse()
        n_true = Tinv.rotate(NORMAL)
        prior = rotation_between([0, 0, 1], unit(rng.normal(0, 1, 3))) @ [0, 0, 1]
        prior = unit(n_true + 0.09 * (prior - (prior @ n_true) * n_true))  # ~5 deg off
        m = measure_marker(img, camera, radius, prior_normal=prior)
        if m.status is not MeasurementStatus.OK or m.pose is None:
            failures += 1
            continue
        errors.append(np.concatenate([m.pose.center - Tinv.apply(MARKER), m.pose.normal - n_true]))
        edge_blurs.append(m.blur_sigma)
    # Mean squared error, so that a bias counts too; too few successes: unknown.
    var = np.mean(np.square(errors), axis=0) if len(errors) >= 3 else np.full(6, np.nan)
    edge = float(np.median(edge_blurs)) if edge_blurs else math.nan
    return CellResult(
        d, theta, np.asarray(var, dtype=np.float64), len(errors), failures, blur, edge
    )


def run_experiment(
    distances: Sequence[float],
    bearings: Sequence[float],
    repetitions: int = 20,
    seed: int = 1,
    camera: CameraModel | None = None,
    radius: float = 0.0125,
    noise: SensorNoise | None = None,
    jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> list[CellResult]:
    """Measure the six variances on every (d, theta) cell (seeded per cell: reproducible)."""
    if repetitions < 3:
        raise SensorModelError('need at least 3 repetitions per cell')
    cam = dynamic_camera() if camera is None else camera
    nz = SensorNoise() if noise is None else noise
    tasks = [
        (float(d), float(t), repetitions, seed * 100_003 + i, radius, cam, nz)
        for i, (d, t) in enumerate((d, t) for d in distances for t in bearings)
    ]
    results: list[CellResult] = []
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for r in pool.map(_cell, tasks):
                results.append(r)
                if progress:
                    progress(len(results), len(tasks))
    else:
        for task in tasks:
            results.append(_cell(task))
            if progress:
                progress(len(results), len(tasks))
    return results


BLUR_DISTANCES = (0.5, 0.7)
BLUR_BEARINGS = (math.radians(20.0), math.radians(50.0))
BLURS = (0.0, 2.0, 4.0, 8.0)


def run_blur_study(
    blurs: Sequence[float] = BLURS,
    distances: Sequence[float] = BLUR_DISTANCES,
    bearings: Sequence[float] = BLUR_BEARINGS,
    repetitions: int = 20,
    seed: int = 1,
    camera: CameraModel | None = None,
    radius: float = 0.0125,
    jobs: int = 1,
) -> list[CellResult]:
    """The same cells rendered through a defocus blur of each of ``blurs`` px (the third
    factor of the model: :func:`fit_blur`); seeded per (d, theta) cell alike for every blur,
    so that blur is the only change."""
    cam = dynamic_camera() if camera is None else camera
    cells = [(float(d), float(t)) for d in distances for t in bearings]
    tasks = [
        (d, t, repetitions, seed * 200_003 + i, radius, cam, SensorNoise(), float(b))
        for b in blurs
        for i, (d, t) in enumerate(cells)
    ]
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            return list(pool.map(_cell, tasks))
    return [_cell(task) for task in tasks]


def fit_blur(model: SensorModel, cells: Sequence[CellResult]) -> SensorModel:
    """``model`` with the blur coefficients the blur study measured: per variable, the least
    squares slope (through the origin, >= 0) of each cell's log variance ratio to its own
    unblurred cell against ``log(1 + (b / B0)^2)``, ``b`` the blur the detector saw beyond the
    sharp cells' (``blur_base``).

    Raises:
        SensorModelError: without unblurred and blurred cells of the same (d, theta).
    """
    sharp = {(c.distance, c.bearing): c for c in cells if c.blur == 0.0}
    base_seen = [c.edge_blur for c in sharp.values() if math.isfinite(c.edge_blur)]
    base = float(np.median(base_seen)) if base_seen else 0.0
    x, y = [], []
    for c in cells:
        ref = sharp.get((c.distance, c.bearing))
        if c.blur <= 0.0 or ref is None:
            continue
        ok = np.isfinite(c.variances) & np.isfinite(ref.variances) & (ref.variances > 0)
        if not np.all(ok) or np.any(c.variances <= 0):
            continue
        # The blur as the imager will see it: the edges' beyond a sharp view's (the detector
        # reads a very blurred edge a little short), else the blur rendered.
        seen = (
            math.sqrt(max(c.edge_blur**2 - base**2, 0.0)) if math.isfinite(c.edge_blur) else c.blur
        )
        x.append(float(blur_term(seen)))
        y.append(np.log(c.variances / ref.variances))
    if not x:
        raise SensorModelError('the blur study has no blurred cell beside its sharp one')
    X, Y = np.asarray(x), np.asarray(y)
    cb = np.clip((X @ Y) / float(X @ X), 0.0, None)
    samples = dict(model.samples)
    samples['blur_study'] = {
        'blur_px': [c.blur for c in cells],
        'distance': [c.distance for c in cells],
        'bearing': [c.bearing for c in cells],
        'variances': {v: [float(c.variances[i]) for c in cells] for i, v in enumerate(VARIABLES)},
    }
    samples['blur_study']['edge_blur_px'] = [c.edge_blur for c in cells]
    return replace(
        model,
        blur_coefficients=cb,
        blur_base=base,
        samples=samples,
    )


def fit_model(cells: Sequence[CellResult], max_bearing: float = math.radians(75.0)) -> SensorModel:
    """Fit the log-variance response surfaces to the measured cells.

    Raises:
        SensorModelError: if fewer than 6 cells have usable measurements.
    """
    good = [c for c in cells if np.all(np.isfinite(c.variances)) and np.all(c.variances > 0)]
    if len(good) < N_TERMS:
        raise SensorModelError(
            f'only {len(good)} usable cells; need at least {N_TERMS} for the fit'
        )
    X = np.array([design_row(c.distance, c.bearing) for c in good])
    Y = np.log(np.array([c.variances for c in good]))
    # With fewer distinct levels than a full quadratic needs, lstsq returns the minimum-norm fit.
    coeffs, *_ = np.linalg.lstsq(X, Y, rcond=None)
    ds = [c.distance for c in cells]
    ts = [c.bearing for c in cells]
    samples = {
        'distance': [c.distance for c in cells],
        'bearing': [c.bearing for c in cells],
        'successes': [c.successes for c in cells],
        'failures': [c.failures for c in cells],
        'variances': {v: [float(c.variances[i]) for c in cells] for i, v in enumerate(VARIABLES)},
    }
    return SensorModel(coeffs.T, (min(ds), max(ds)), (min(ts), max(ts)), max_bearing, samples)


def plot_model(model: SensorModel, path: Path) -> None:
    """Response surfaces like the paper's Fig. 16 (all six variances; log scale)."""
    import matplotlib  # heavy: only when a figure is drawn

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    d = np.linspace(*model.d_range, 25)
    t = np.linspace(*model.theta_range, 25)
    D, Tg = np.meshgrid(d, t)
    fig = plt.figure(figsize=(15, 9))
    units = ['mm$^2$'] * 3 + [''] * 3
    scale = [1e6] * 3 + [1.0] * 3
    s = model.samples
    for i, name in enumerate(VARIABLES):
        ax = fig.add_subplot(2, 3, i + 1, projection='3d')
        Z = np.vectorize(lambda a, b, i=i: model.variances(a, b)[i])(D, Tg) * scale[i]
        ax.plot_surface(1e3 * D, np.degrees(Tg), np.log10(Z), cmap='viridis', alpha=0.8)
        if s:
            v = np.array(s['variances'][name]) * scale[i]
            ok = np.isfinite(v) & (v > 0)
            ax.scatter(
                1e3 * np.array(s['distance'])[ok],
                np.degrees(np.array(s['bearing']))[ok],
                np.log10(v[ok]),
                color='k',
                s=8,
            )
        ax.set_xlabel('distance d [mm]')
        ax.set_ylabel('bearing θ [deg]')
        ax.set_zlabel(f'log10 σ² {units[i]}')
        ax.set_title(f'σ²({name})')
    fig.suptitle('Sensor model: variance response surfaces (camera frame), cf. paper Fig. 16')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(',') if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f'expected comma-separated numbers: {text}') from exc


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='activesurv_sensor_model',
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument('--out', type=Path, required=True, help='output directory')
    parser.add_argument('--distances', type=_floats, default=[0.40, 0.50, 0.60, 0.70, 0.80])
    parser.add_argument('--bearings-deg', type=_floats, default=[0, 10, 20, 30, 40, 50, 60, 70])
    parser.add_argument('--repetitions', type=int, default=20)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--jobs', type=int, default=os.cpu_count() or 1)
    parser.add_argument(
        '--blurs',
        type=_floats,
        default=list(BLURS),
        help='defocus blurs (px) of the blur study (the model\'s third factor); "0": none',
    )
    args = parser.parse_args(argv)
    try:
        if any(d <= 0 for d in args.distances) or any(not 0 <= b < 90 for b in args.bearings_deg):
            raise SensorModelError('distances must be > 0 and bearings in [0, 90) degrees')
        if any(not 0 <= b <= 12 for b in args.blurs):
            raise SensorModelError('blurs must be in [0, 12] px')
        args.out.mkdir(parents=True, exist_ok=True)

        def progress(done: int, total: int) -> None:
            print(f'sensor model: cell {done}/{total}', flush=True)

        cells = run_experiment(
            args.distances,
            [math.radians(b) for b in args.bearings_deg],
            args.repetitions,
            args.seed,
            jobs=args.jobs,
            progress=progress,
        )
        model = fit_model(cells)
        if any(b > 0 for b in args.blurs):
            print('sensor model: the blur study', flush=True)
            blurs = sorted({0.0, *args.blurs})
            model = fit_blur(model, run_blur_study(blurs, seed=args.seed, jobs=args.jobs))
        model.save(args.out / 'sensor_model.yaml')
        plot_model(model, args.out / 'sensor_model.png')
    except (SensorModelError, OSError) as exc:
        print(f'activesurv_sensor_model: error: {exc}', file=sys.stderr)
        return 1
    print(f'wrote {args.out / "sensor_model.yaml"} and {args.out / "sensor_model.png"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
