"""Render the project's physically based test set of the paper's target (issue 33, item 5).

A development tool, run once: it needs Mitsuba 3 (``pip install -r requirements-dev.txt``), which
neither ``make test`` nor ``make bench`` does; they read the stored images. Usage::

    python scripts/render_photoreal.py --out test/data/photoreal [--per-case 5] [--spp 128]

Each image is the paper's target (a matte black 60 mm plate, a white disc of 12.5 mm radius on
it, Table I) on a vertical face of the object, on a textured table in a cell with clutter, lit
by a ceiling panel (and a side panel where the case says), path-traced (Mitsuba 3, ``path``
integrator, CPU ``scalar_rgb``) through the dynamic camera's intrinsics (640x480, fx = fy =
5000 px: a 25 mm lens on 5 um pixels), then through a sensor: the exposure (the white disc at
~230 grey levels, or ~90 for ``dim``), shot noise (40 e- per grey level) and read noise (1
level), the camera's response (gamma 1, 1.6 or 2.2) and 8-bit quantisation. Cases:

* ``nominal``: in focus (pinhole), ceiling light.
* ``glossy``: the plate anodised with a sheen (rough plastic) instead of matte.
* ``side_light``: a strong panel at the side at a grazing angle as well.
* ``bright_table``: a light table and a light wall behind the plate.
* ``dim``: the white disc at ~90 grey levels.
* ``defocus``: a thin lens at f/2.8-f/4 focused 10-15 % off the marker.
* ``motion_blur``: the object moving 1-3 mm during the exposure (8 sub-frames averaged).
* ``distractor``: a second plate with a white disc beside the target, in view.

Written: ``<case>_<k>.png`` (8-bit grey) and ``truth.json``: per image the camera (K, the pose
of its optical frame in the world: x right, y down, z forward), the disc's centre and normal,
the predicted normal and image position a run would give (the truth a few degrees and pixels
off), the gamma, the exposure's streak; and the convention check: a fronto-parallel disc's
image centroid against K's projection of its centre (must agree within 0.01 px).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.geometry import Transform

CASES = (
    'nominal',
    'glossy',
    'side_light',
    'bright_table',
    'dim',
    'defocus',
    'motion_blur',
    'distractor',
)
RADIUS = 0.0125  # m, the side marker (Table I)
PLATE_HALF = 0.03  # m
WHITE = 0.80  # the disc's diffuse reflectance
BLACK = 0.035  # the anodised plate's
E_PER_LEVEL = 40.0
READ_NOISE = 1.0
FOCAL_LENGTH = 0.025  # m: fx 5000 px on 5 um pixels


def _mi() -> Any:
    try:
        import mitsuba as mi
    except ImportError:
        sys.exit('render_photoreal: needs Mitsuba 3: pip install -r requirements-dev.txt')
    mi.set_variant('scalar_rgb')
    return mi


def _look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> Transform:
    """Our optical frame (x right, y down, z forward) at ``eye`` looking at ``target``."""
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return Transform(np.column_stack([x, y, z]), eye)


def _to_world(mi: Any, R: np.ndarray, t: np.ndarray, scale: tuple[float, float, float]) -> Any:
    m = np.eye(4)
    m[:3, :3] = R @ np.diag(scale)
    m[:3, 3] = t
    return mi.ScalarTransform4f(m.tolist())


def _frame_of_normal(n: np.ndarray) -> np.ndarray:
    """A rotation taking +z to ``n`` (x kept horizontal)."""
    n = n / np.linalg.norm(n)
    x = np.cross([0.0, 0.0, 1.0], n)
    if np.linalg.norm(x) < 1e-6:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(n, x)
    return np.column_stack([x, y, n])


def _camera_to_world(mi: Any, T: Transform) -> Any:
    # Mitsuba's camera looks along +z with +y up and +x to the image's left: ours turned
    # 180 degrees about z (checked by the convention render, see check_convention).
    return _to_world(mi, T.R @ np.diag([-1.0, -1.0, 1.0]), T.t, (1.0, 1.0, 1.0))


def _sensor(mi: Any, T: Transform, spp: int, lens: dict[str, float] | None) -> dict[str, Any]:
    cam = dynamic_camera('cam1')
    fov = math.degrees(2.0 * math.atan(cam.width / 2.0 / cam.fx))
    s: dict[str, Any] = {
        'type': 'perspective' if lens is None else 'thinlens',
        'fov': fov,
        'fov_axis': 'x',
        'to_world': _camera_to_world(mi, T),
        'film': {
            'type': 'hdrfilm',
            'width': cam.width,
            'height': cam.height,
            'rfilter': {'type': 'box'},
            'pixel_format': 'rgb',
        },
        'sampler': {'type': 'independent', 'sample_count': spp},
    }
    if lens is not None:
        s['aperture_radius'] = lens['aperture_radius']
        s['focus_distance'] = lens['focus_distance']
    return s


def _texture(rng: np.random.Generator, mean: float, contrast: float) -> np.ndarray:
    """A wood-grain-like table texture (grey reflectance, 256x256)."""
    n = 256
    base = rng.normal(0.0, 1.0, (n, n)).astype(np.float32)
    grain = cv2.GaussianBlur(base, (0, 0), sigmaX=12.0, sigmaY=1.5)
    grain = (grain - grain.mean()) / (grain.std() + 1e-9)
    tex = np.clip(mean * (1.0 + contrast * grain), 0.02, 0.95)
    return np.repeat(tex[:, :, None], 3, axis=2)


def _plate(
    mi: Any, centre: np.ndarray, normal: np.ndarray, glossy: bool
) -> tuple[dict[str, Any], dict[str, Any]]:
    R = _frame_of_normal(normal)
    if glossy:
        bsdf = {
            'type': 'roughplastic',
            'diffuse_reflectance': {'type': 'rgb', 'value': BLACK},
            'alpha': 0.12,
        }
    else:
        bsdf = {'type': 'diffuse', 'reflectance': {'type': 'rgb', 'value': BLACK}}
    plate = {
        'type': 'cube',
        # a 4 mm thick plate whose front face is at the disc's plane
        'to_world': _to_world(mi, R, centre - 0.002 * normal, (PLATE_HALF, PLATE_HALF, 0.002)),
        'bsdf': bsdf,
    }
    disc = {
        'type': 'disk',
        'to_world': _to_world(mi, R, centre + 2e-5 * normal, (RADIUS, RADIUS, 1.0)),
        'bsdf': {'type': 'diffuse', 'reflectance': {'type': 'rgb', 'value': WHITE}},
    }
    return plate, disc


def _scene(
    mi: Any,
    case: str,
    rng: np.random.Generator,
    T: Transform,
    centre: np.ndarray,
    normal: np.ndarray,
    spp: int,
    lens: dict[str, float] | None,
) -> dict[str, Any]:
    bright = case == 'bright_table'
    scene: dict[str, Any] = {
        'type': 'scene',
        'integrator': {'type': 'path', 'max_depth': 4},
        'sensor': _sensor(mi, T, spp, lens),
        'ceiling': {
            'type': 'rectangle',
            'to_world': _to_world(
                mi, np.diag([1.0, -1.0, -1.0]), np.array([0.0, 0.0, 1.2]), (0.6, 0.6, 1.0)
            ),
            'emitter': {'type': 'area', 'radiance': {'type': 'rgb', 'value': 3.0}},
        },
        'ambient': {'type': 'constant', 'radiance': {'type': 'rgb', 'value': 0.15}},
        'table': {
            'type': 'rectangle',
            'to_world': _to_world(mi, np.eye(3), np.array([0.0, 0.0, -0.05]), (1.0, 1.0, 1.0)),
            'bsdf': {
                'type': 'diffuse',
                'reflectance': {
                    'type': 'bitmap',
                    'bitmap': mi.Bitmap(_texture(rng, 0.55 if bright else 0.25, 0.35)),
                    'raw': True,
                },
            },
        },
    }
    # The object: a box behind the plate (its face carries the plate), and a wall behind.
    R = _frame_of_normal(normal)
    scene['object'] = {
        'type': 'cube',
        'to_world': _to_world(mi, R, centre - 0.045 * normal, (0.05, 0.05, 0.04)),
        'bsdf': {'type': 'diffuse', 'reflectance': {'type': 'rgb', 'value': 0.3}},
    }
    wall = centre - 0.45 * normal
    scene['wall'] = {
        'type': 'rectangle',
        'to_world': _to_world(mi, R, wall, (1.0, 1.0, 1.0)),
        'bsdf': {
            'type': 'diffuse',
            'reflectance': {'type': 'rgb', 'value': 0.7 if bright else 0.18},
        },
    }
    # Clutter: a few boxes on the table around the object.
    for k in range(4):
        p = centre + np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), 0.0])
        p[2] = -0.05 + 0.02
        if np.linalg.norm(p[:2] - centre[:2]) < 0.12:
            continue
        scene[f'clutter{k}'] = {
            'type': 'cube',
            'to_world': _to_world(
                mi,
                _frame_of_normal(np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), 0.0])),
                p,
                (0.03, 0.02, 0.02),
            ),
            'bsdf': {
                'type': 'diffuse',
                'reflectance': {'type': 'rgb', 'value': rng.uniform(0.1, 0.7)},
            },
        }
    if case == 'side_light':
        side = centre + 0.5 * _frame_of_normal(normal)[:, 0] + 0.1 * normal
        d = centre - side
        scene['side'] = {
            'type': 'rectangle',
            'to_world': _to_world(mi, _frame_of_normal(d), side, (0.08, 0.08, 1.0)),
            'emitter': {'type': 'area', 'radiance': {'type': 'rgb', 'value': 40.0}},
        }
    return scene


def _radiance(mi: Any, scene: dict[str, Any], seed: int = 0) -> np.ndarray:
    """Luminance; ``seed``: the sampler's (sub-frames of one exposure need their own, or their
    path-tracing noise is the same and does not average out)."""
    img = np.array(mi.render(mi.load_dict(scene), seed=seed), dtype=np.float64)
    return 0.2126 * img[:, :, 0] + 0.7152 * img[:, :, 1] + 0.0722 * img[:, :, 2]


def _expose(
    radiance: np.ndarray, scale: float, gamma: float, rng: np.random.Generator
) -> np.ndarray:
    levels = np.maximum(radiance * scale, 0.0)
    electrons = rng.poisson(levels * E_PER_LEVEL) / E_PER_LEVEL
    levels = electrons + rng.normal(0.0, READ_NOISE, levels.shape)
    x = np.clip(levels / 255.0, 0.0, 1.0) ** (1.0 / gamma)
    return np.clip(np.rint(255.0 * x), 0, 255).astype(np.uint8)


def check_convention(mi: Any, spp: int) -> dict[str, float]:
    """A lone fronto-parallel disc, pinhole, no noise: its image's centroid against K's
    projection of its centre (px)."""
    cam = dynamic_camera('cam1')
    T = _look_at(np.array([0.0, -0.55, 0.0]), np.array([0.0, 0.0, 0.0]), np.array([0, 0, 1.0]))
    centre = np.array([0.0070, 0.0, -0.0045])  # right of and below the optical axis
    scene = {
        'type': 'scene',
        'integrator': {'type': 'direct'},
        'sensor': _sensor(mi, T, spp, None),
        'disc': {
            'type': 'disk',
            'to_world': _to_world(
                mi, _frame_of_normal(np.array([0.0, -1.0, 0.0])), centre, (0.004, 0.004, 1.0)
            ),
            'emitter': {'type': 'area', 'radiance': {'type': 'rgb', 'value': 1.0}},
        },
    }
    img = _radiance(mi, scene)
    v, u = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    w = img / img.sum()
    seen = np.array([(w * u).sum(), (w * v).sum()])
    p = T.R.T @ (centre - T.t)
    expected = cam.project(p[None, :])[0]
    return {
        'centroid_u': float(seen[0]),
        'centroid_v': float(seen[1]),
        'projected_u': float(expected[0]),
        'projected_v': float(expected[1]),
        'error_px': float(np.linalg.norm(seen - expected)),
    }


def _one(mi: Any, case: str, k: int, spp: int, out: Path) -> dict[str, Any]:
    rng = np.random.default_rng(1000 * CASES.index(case) + k)
    cam = dynamic_camera('cam1')
    # The object's side plate on the table, facing a camera at the stages' height.
    yaw = rng.uniform(-math.pi, math.pi)
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    centre = np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), 0.0])
    dist = rng.uniform(0.48, 0.62)
    theta = math.radians(rng.uniform(5.0, 40.0)) * (1 if rng.random() < 0.5 else -1)
    dirn = _frame_of_normal(normal) @ np.array([math.sin(theta), 0.0, math.cos(theta)])
    eye = centre + dist * dirn + np.array([0.0, 0.0, rng.uniform(-0.02, 0.05)])
    aim = centre + rng.normal(0.0, 0.004, 3)  # the stage's pointing error
    T = _look_at(eye, aim, np.array([0.0, 0.0, 1.0]))
    lens = None
    if case == 'defocus':
        n_stop = rng.uniform(2.8, 4.0)
        off = rng.uniform(0.10, 0.15) * (1 if rng.random() < 0.5 else -1)
        lens = {
            'aperture_radius': FOCAL_LENGTH / (2.0 * n_stop),
            'focus_distance': float(np.linalg.norm(centre - eye) * (1.0 + off)),
        }
    scene = _scene(mi, case, rng, T, centre, normal, spp, lens)
    plate, disc = _plate(mi, centre, normal, case == 'glossy')
    scene['plate'], scene['disc'] = plate, disc
    velocity = np.zeros(3)
    exposure = 0.01
    if case == 'distractor':
        side = _frame_of_normal(normal)[:, 0] * rng.choice([-1.0, 1.0]) * rng.uniform(0.065, 0.08)
        p2, d2 = _plate(mi, centre + side, normal, False)
        scene['plate2'], scene['disc2'] = p2, d2
    if case == 'motion_blur':
        sweep = rng.uniform(0.001, 0.003)
        along = _frame_of_normal(normal)[:, 0] * rng.choice([-1.0, 1.0])
        velocity = along * sweep / exposure
        acc = np.zeros((cam.height, cam.width))
        subs = 8
        for j in range(subs):
            shift = velocity * exposure * ((j + 0.5) / subs - 0.5)
            moved = dict(scene)
            moved['sensor'] = _sensor(mi, T, max(spp // subs, 8), None)
            moved['plate'], moved['disc'] = _plate(mi, centre + shift, normal, False)
            moved['object'] = {
                **scene['object'],
                'to_world': _to_world(
                    mi,
                    _frame_of_normal(normal),
                    centre + shift - 0.045 * normal,
                    (0.05, 0.05, 0.04),
                ),
            }
            acc += _radiance(mi, moved, seed=j)
        radiance = acc / subs
    else:
        radiance = _radiance(mi, scene)
    # Exposure: the disc's white at ~230 grey levels (``dim``: ~90), read off the render.
    p_cam = T.R.T @ (centre - T.t)
    uv = cam.project(p_cam[None, :])[0]
    r_px = RADIUS * cam.fx / p_cam[2]
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    inside = (u - uv[0]) ** 2 + (v - uv[1]) ** 2 < (0.5 * r_px) ** 2
    white = float(np.median(radiance[inside]))
    target = 90.0 if case == 'dim' else 230.0
    gamma = float(rng.choice([1.0, 1.6, 2.2]))
    gray = _expose(radiance, target / white, gamma, rng)
    name = f'{case}_{k}.png'
    cv2.imwrite(str(out / name), gray)
    # What a run would give the imager: the predicted normal a few degrees off, the predicted
    # position a few pixels off.
    tilt = np.radians(rng.uniform(1.0, 4.0))
    axis = np.cross(normal, rng.normal(0.0, 1.0, 3))
    axis /= np.linalg.norm(axis)
    predicted = normal * math.cos(tilt) + np.cross(axis, normal) * math.sin(tilt)
    streak = np.zeros(2)
    if np.any(velocity):
        a = cam.project((T.R.T @ (centre - 0.5 * velocity * exposure - T.t))[None, :])[0]
        b = cam.project((T.R.T @ (centre + 0.5 * velocity * exposure - T.t))[None, :])[0]
        streak = b - a
    return {
        'image': name,
        'case': case,
        'camera': {
            'width': cam.width,
            'height': cam.height,
            'K': cam.K.tolist(),
            'R_world_camera': T.R.tolist(),
            't_world_camera': T.t.tolist(),
        },
        'radius': RADIUS,
        'centre': centre.tolist(),
        'normal': normal.tolist(),
        'predicted_normal': predicted.tolist(),
        'predicted_uv': (uv + rng.normal(0.0, 3.0, 2)).tolist(),
        'gamma': gamma,
        'exposure_time': exposure,
        'velocity': velocity.tolist(),
        'streak_px': streak.tolist(),
        'lens': lens,
        'white_level': target,
        'spp': spp,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', required=True, type=Path)
    ap.add_argument('--per-case', type=int, default=5)
    ap.add_argument('--spp', type=int, default=128)
    ap.add_argument('--cases', nargs='*', default=list(CASES), choices=CASES)
    args = ap.parse_args(argv)
    if args.out.exists() and any(args.out.iterdir()):
        sys.exit(f'render_photoreal: {args.out} is not empty; choose a new directory')
    args.out.mkdir(parents=True, exist_ok=True)
    mi = _mi()
    started = time.monotonic()
    convention = check_convention(mi, 1024)
    print(f'convention: centroid vs K projection {convention["error_px"]:.4f} px', flush=True)
    images = []
    for case in args.cases:
        for k in range(args.per_case):
            t0 = time.monotonic()
            images.append(_one(mi, case, k, args.spp, args.out))
            print(f'{case}_{k}: {time.monotonic() - t0:.1f} s', flush=True)
    doc = {
        'renderer': f'Mitsuba {mi.__version__} scalar_rgb, path tracing',
        'sensor': {'electrons_per_level': E_PER_LEVEL, 'read_noise': READ_NOISE},
        'convention': convention,
        'images': images,
    }
    (args.out / 'truth.json').write_text(json.dumps(doc, indent=1) + '\n')
    print(f'{len(images)} images in {time.monotonic() - started:.0f} s -> {args.out}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
