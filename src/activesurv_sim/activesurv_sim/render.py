"""Render what a camera sees: flat plates carrying a circular marker or a checkerboard.

This is the simulated camera's core and the source of the "real pixels" the pipeline runs on in
simulation. A scene is a list of :class:`Plate` (a rectangle in 3-D with a pattern drawn on it)
in front of a uniform background. Two ways to anti-alias the edges (``SensorNoise.antialias``):

* ``coverage`` (default): every pixel centre of a plate's projected box is ray-cast (in
  float32, through rays precomputed per pixel, so lens distortion is honoured). Each boundary
  (plate edge, disc rim, checker line) is a signed distance in the plate plane; divided by its
  gradient in pixels (from the local plate-to-pixel Jacobian) it gives the fraction of the pixel
  on either side, as a box filter across the edge would. Plates are composited by depth.
  The pixels of a plain or disc plate are a compiled loop (:mod:`activesurv_sim.render_kernels`,
  the same float32 arithmetic as the array code boards still use).
* ``supersample``: pixels on an edge (a neighbour has another label) are re-rendered with
  ``supersample x supersample`` rays (float64); slower, kept as the reference.

Then the lens and shutter act (:class:`FrameOptics`: a motion streak over the exposure, the lens's
blur with the depth of field's, the exposure's gain), photon shot noise and read noise are added
to the linear levels, the camera's response (gamma) applied, and it is
quantised to 8 bits, all only inside the plates' region (plus the blur's reach). Outside it the
frame is uniform background, so its noisy pixels are taken as a window at a random offset of a
pool of noisy background drawn once per renderer. Inside, the per-pixel noise (its standard
deviation follows each pixel's level) scales standard normal draws taken, the same way, from a
pool drawn once: drawing 300,000 normals cost more than the rest of a frame. A frame's noise is
therefore a shifted copy of another frame's; no measurement here combines frames, and each
frame's noise has the right distribution. Everything random comes from a seeded
``numpy.random.Generator``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, as_vector3, cross3, unit
from activesurv_sim import render_kernels as kernels
from activesurv_sim.errors import RenderError
from activesurv_sim.frame_optics import IDEAL_OPTICS, FrameOptics

Array = NDArray[np.float64]

BLACK_PLATE = 25.0  # matte black anodised aluminium (Table I), in 8-bit grey levels
WHITE_MARKER = 230.0
BACKGROUND = 70.0


class Pattern(Enum):
    PLAIN = 'plain'
    DISC = 'disc'
    CHECKER = 'checker'


@dataclass(frozen=True)
class Plate:
    """A flat rectangle in the world.

    Attributes:
        center: plate centre (3,), also the centre of its disc or board.
        normal: unit normal of the visible face (3,).
        x_axis: in-plane direction of the plate's first side (made orthogonal to ``normal``).
        half_size: half extents (along x_axis, along normal x x_axis), metres.
        pattern: what is drawn on it.
        radius: disc radius (DISC), metres.
        squares: (columns, rows) of the board (CHECKER).
        square_size: side of one square (CHECKER), metres.
        plate_level / mark_level: grey levels of the plate and of the marker or white squares.
    """

    center: Array
    normal: Array
    x_axis: Array
    half_size: tuple[float, float]
    pattern: Pattern = Pattern.PLAIN
    radius: float = 0.0
    squares: tuple[int, int] = (0, 0)
    square_size: float = 0.0
    plate_level: float = BLACK_PLATE
    mark_level: float = WHITE_MARKER
    one_sided: bool = False  # a face of a solid: not drawn from behind

    @staticmethod
    def disc(
        center: ArrayLike,
        normal: ArrayLike,
        radius: float,
        plate_half_size: float = 0.06,
        x_axis: ArrayLike = (1.0, 0.0, 0.0),
    ) -> Plate:
        """A matte black square plate with a white disc at its centre (the paper's target)."""
        n = unit(normal, 'normal')
        x = _orthogonal_axis(n, x_axis)
        if not radius > 0.0 or radius >= plate_half_size:
            raise RenderError(f'disc radius {radius} must be > 0 and fit on the plate')
        return Plate(
            as_vector3(center, 'center'),
            n,
            x,
            (plate_half_size, plate_half_size),
            Pattern.DISC,
            radius=radius,
        )

    @staticmethod
    def checkerboard(
        center: ArrayLike,
        normal: ArrayLike,
        x_axis: ArrayLike,
        squares: tuple[int, int],
        square_size: float,
        margin: float = 0.01,
    ) -> Plate:
        """A calibration board of ``squares`` = (columns, rows) squares, centred on ``center``."""
        n = unit(normal, 'normal')
        x = _orthogonal_axis(n, x_axis)
        half = (squares[0] * square_size / 2 + margin, squares[1] * square_size / 2 + margin)
        return Plate(
            as_vector3(center, 'center'),
            n,
            x,
            half,
            Pattern.CHECKER,
            squares=squares,
            square_size=square_size,
            plate_level=WHITE_MARKER,
            mark_level=BLACK_PLATE,
        )

    @property
    def y_axis(self) -> Array:
        return cross3(self.normal, self.x_axis)


def _orthogonal_axis(n: Array, x_axis: ArrayLike) -> Array:
    x = as_vector3(x_axis, 'x_axis')
    x = x - (x @ n) * n
    if np.linalg.norm(x) < 1e-9:  # x_axis parallel to the normal: pick any in-plane direction
        x = cross3(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    return unit(x)


@dataclass(frozen=True)
class SensorNoise:
    """Image formation after the optics.

    Attributes:
        blur_sigma: Gaussian blur of the lens/defocus, pixels (0: none).
        electrons_per_level: photo-electrons per grey level (shot noise; 0: none).
        read_noise: read noise std in grey levels.
        supersample: with ``antialias='supersample'``, edge pixels get supersample^2 rays.
        antialias: ``coverage`` (analytic edge coverage, fast) or ``supersample``.
    """

    blur_sigma: float = 0.8
    electrons_per_level: float = 40.0
    read_noise: float = 1.0
    supersample: int = 8
    antialias: str = 'coverage'


def _streaked(img: NDArray[np.float32], streak: tuple[float, float]) -> NDArray[np.float32]:
    """``img`` smeared uniformly along the image vector ``streak`` (px), centred: the shutter
    open while the marker moved that far."""
    length = math.hypot(*streak)
    if length < 0.5:
        return img
    r = math.ceil(length / 2.0) + 1
    kernel = np.zeros((2 * r + 1, 2 * r + 1), dtype=np.float32)
    n = max(2, math.ceil(4.0 * length))
    for k in np.linspace(-0.5, 0.5, n):
        x, y = r + k * streak[0], r + k * streak[1]
        x0, y0 = math.floor(x), math.floor(y)
        fx, fy = x - x0, y - y0
        kernel[y0, x0] += (1 - fx) * (1 - fy)
        kernel[y0, x0 + 1] += fx * (1 - fy)
        kernel[y0 + 1, x0] += (1 - fx) * fy
        kernel[y0 + 1, x0 + 1] += fx * fy
    kernel /= kernel.sum()
    return np.asarray(
        cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REPLICATE), dtype=np.float32
    )


def _encode(img: NDArray[np.float32], gamma: float) -> NDArray[np.float32]:
    """Linear levels through the camera's response (gamma 1: unchanged)."""
    if gamma == 1.0:
        return img
    x = np.clip(img, np.float32(0.0), np.float32(255.0)) / np.float32(255.0)
    return np.asarray(np.float32(255.0) * x ** np.float32(1.0 / gamma), dtype=np.float32)


@dataclass(frozen=True)
class Scene:
    plates: tuple[Plate, ...]
    background: float = BACKGROUND
    ambient_gradient: tuple[float, float] = field(default=(0.0, 0.0))  # grey levels across x, y


def _shade(
    scene: Scene,
    origin: Array,
    dirs: Array,
    only: int | None = None,
    best_t: Array | None = None,
    level: Array | None = None,
    label: NDArray[np.int64] | None = None,
    rotation: Array | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Grey level and a label (which plate and which part of its pattern) for each ray.

    With ``only``, just that plate is tested, against (and updating) the given depth, level and
    label buffers. With ``rotation`` (world from camera), ``dirs`` are in the camera frame: the
    rotation is folded into each plate's 3x3 axis matrix instead of applied to every ray.
    """
    n_rays = dirs.shape[0]
    best_t = np.full(n_rays, np.inf) if best_t is None else best_t
    level = np.full(n_rays, scene.background) if level is None else level
    label = np.zeros(n_rays, dtype=np.int64) if label is None else label
    for p_idx, plate in enumerate(scene.plates):
        if only is not None and p_idx != only:
            continue
        # One 3x3 product gives, per ray, its component along the normal and the two in-plane
        # axes; the hit's plate coordinates are then a0 + t * d (no n x 3 temporaries).
        y_axis = plate.y_axis
        axes = np.column_stack([plate.normal, plate.x_axis, y_axis])
        comps = dirs @ (axes if rotation is None else rotation.T @ axes)
        denom = comps[:, 0]
        rel0 = origin - plate.center
        with np.errstate(divide='ignore', invalid='ignore'):
            t = -(rel0 @ plate.normal) / denom
        ok = (t > 0.0) & (t < best_t) & (np.abs(denom) > 1e-12) & np.isfinite(t)
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            continue
        t_ok = t[idx]
        a = (rel0 @ plate.x_axis) + t_ok * comps[idx, 1]
        b = (rel0 @ y_axis) + t_ok * comps[idx, 2]
        inside = (np.abs(a) <= plate.half_size[0]) & (np.abs(b) <= plate.half_size[1])
        idx, a, b = idx[inside], a[inside], b[inside]
        if idx.size == 0:
            continue
        best_t[idx] = t[idx]
        vals = np.full(idx.size, plate.plate_level)
        lab = np.full(idx.size, 2 * p_idx + 1)
        if plate.pattern is Pattern.DISC:
            on = a * a + b * b <= plate.radius * plate.radius
            vals[on] = plate.mark_level
            lab[on] = 2 * p_idx + 2
        elif plate.pattern is Pattern.CHECKER:
            cols, rows = plate.squares
            s = plate.square_size
            ia = np.floor(a / s + cols / 2).astype(np.int64)
            ib = np.floor(b / s + rows / 2).astype(np.int64)
            on_board = (ia >= 0) & (ia < cols) & (ib >= 0) & (ib < rows)
            dark = on_board & ((ia + ib) % 2 == 0)
            vals[dark] = plate.mark_level
            lab[dark] = 2 * p_idx + 2
        level[idx] = vals
        label[idx] = lab
    return level, label


def _back_face(plate: Plate, T_world_camera: Transform) -> bool:
    """A one-sided plate seen from behind (a solid's face turned away: its other faces
    hide whatever it would)."""
    return plate.one_sided and float((T_world_camera.t - plate.center) @ plate.normal) <= 0.0


ANTIALIAS = ('coverage', 'supersample')
_FAR = kernels.FAR  # plate coordinate (m) given to rays that miss a plate's plane


class Renderer:
    """Renders frames for one camera; keeps the camera-frame ray of every pixel between frames.

    Only pixels inside the projected bounding box of some plate are ray-cast; the rest of the
    image is the uniform background, exactly, so this changes no pixel.
    """

    def __init__(self, camera: CameraModel) -> None:
        self.camera = camera
        h, w = camera.height, camera.width
        uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        self._rays = camera.rays(np.column_stack([uu.ravel(), vv.ravel()])).reshape(h, w, 3)
        self._rays32 = np.ascontiguousarray(self._rays, dtype=np.float32)
        self._pools: dict[tuple[float, float, float, float], NDArray[np.uint8]] = {}
        self._pool_normals: NDArray[np.float32] | None = None
        # The last coverage frame before the sensor: (what it showed, its window, levels).
        self._last: (
            tuple[tuple[object, ...], tuple[int, int, int, int], NDArray[np.float32]] | None
        ) = None

    def _plate_box(self, plate: Plate, T: Transform) -> tuple[int, int, int, int] | None:
        """Pixel bounding box (u0, u1, v0, v1) of a plate, or None when it is not in front."""
        h0, h1 = plate.half_size
        corners = np.array(
            [
                plate.center + sa * h0 * plate.x_axis + sb * h1 * plate.y_axis
                for sa in (-1, 1)
                for sb in (-1, 1)
            ]
        )
        p = (corners - T.t) @ T.R  # camera frame
        if np.any(p[:, 2] <= 1e-6):
            return 0, self.camera.width, 0, self.camera.height  # straddles the camera: all
        px = self.camera.project(p)
        u0, v0 = np.floor(px.min(axis=0)).astype(int) - 3
        u1, v1 = np.ceil(px.max(axis=0)).astype(int) + 4
        u0, u1 = max(u0, 0), min(u1, self.camera.width)
        v0, v1 = max(v0, 0), min(v1, self.camera.height)
        return (u0, u1, v0, v1) if u0 < u1 and v0 < v1 else None

    def render(
        self,
        T_world_camera: Transform,
        scene: Scene,
        noise: SensorNoise | None = None,
        rng: np.random.Generator | None = None,
        optics: FrameOptics = IDEAL_OPTICS,
    ) -> NDArray[np.uint8]:
        """See :func:`render`."""
        noise = SensorNoise() if noise is None else noise
        if noise.supersample < 1:
            raise RenderError('supersample must be >= 1')
        if noise.antialias not in ANTIALIAS:
            raise RenderError(f'antialias must be one of {ANTIALIAS}, got {noise.antialias!r}')
        rng = np.random.default_rng() if rng is None else rng
        boxes = [
            (i, b)
            for i, b in enumerate(
                None if _back_face(pl, T_world_camera) else self._plate_box(pl, T_world_camera)
                for pl in scene.plates
            )
            if b
        ]
        gx, gy = scene.ambient_gradient
        if noise.antialias == 'coverage' and not (gx or gy):
            return self._render_coverage(T_world_camera, scene, noise, rng, boxes, optics)
        img = self._supersampled(T_world_camera, scene, noise, boxes)
        if gx or gy:
            h, w = img.shape
            uu, vv = np.meshgrid(np.arange(w) / w - 0.5, np.arange(h) / h - 0.5)
            img = img + gx * uu + gy * vv
        return _expose(
            self._through_optics(img.astype(np.float32), noise, optics),
            noise,
            rng,
            None,
            optics.gamma,
        )

    @staticmethod
    def _through_optics(
        img: NDArray[np.float32], noise: SensorNoise, optics: FrameOptics
    ) -> NDArray[np.float32]:
        """Motion streak, lens and defocus blur, exposure gain: linear levels still."""
        img = _streaked(img, optics.streak)
        sigma = optics.blur(noise.blur_sigma)
        if sigma > 0.0:
            img = np.asarray(cv2.GaussianBlur(img, (0, 0), sigma), dtype=np.float32)
        if optics.gain != 1.0:
            img = img * np.float32(optics.gain)
        return img

    # -- coverage (default) --------------------------------------------------------------
    def _render_coverage(
        self,
        T: Transform,
        scene: Scene,
        noise: SensorNoise,
        rng: np.random.Generator,
        boxes: list[tuple[int, tuple[int, int, int, int]]],
        optics: FrameOptics = IDEAL_OPTICS,
    ) -> NDArray[np.uint8]:
        cam = self.camera
        out = self._background(scene.background * optics.gain, noise, rng, optics.gamma)
        if not boxes:
            return out
        # A camera and a scene at rest see what they saw: only the sensor's noise is new.
        key = _frame_key(T, scene, noise, optics)
        if self._last is not None and self._last[0] == key:
            _, (V0, V1, U0, U1), img = self._last
            out[V0:V1, U0:U1] = _expose(
                img, noise, rng, self._normals(img.size, rng), optics.gamma
            )
            return out
        # The blur's and the streak's reach beyond the plates.
        m = int(np.ceil(4.0 * optics.blur(noise.blur_sigma) + optics.streak_length)) + 2
        U0 = max(min(b[0] for _, b in boxes) - m, 0)
        U1 = min(max(b[1] for _, b in boxes) + m, cam.width)
        V0 = max(min(b[2] for _, b in boxes) - m, 0)
        V1 = min(max(b[3] for _, b in boxes) + m, cam.height)
        shape = (V1 - V0, U1 - U0)
        bg = np.float32(scene.background)
        img = np.full(shape, bg, dtype=np.float32)
        # Nearest plate first (by the distance to its centre: our plates do not interpenetrate),
        # each takes what the nearer ones left of a pixel: where two plates abut (coverage 1/2
        # each) the background does not show through the seam, and a silhouette over a farther
        # plate blends as alpha compositing would. Work stays inside each plate's box.
        left = np.ones(shape, dtype=np.float32)
        img = np.zeros(shape, dtype=np.float32)
        for i, (u0, u1, v0, v1) in sorted(
            boxes, key=lambda ib: float(np.linalg.norm(scene.plates[ib[0]].center - T.t))
        ):
            cov, lev = self._cover(scene.plates[i], T, (u0, u1, v0, v1))
            win = (slice(v0 - V0, v1 - V0), slice(u0 - U0, u1 - U0))
            take = np.minimum(cov, left[win])
            img[win] += take * lev
            left[win] -= take
        img += left * bg
        img = self._through_optics(img, noise, optics)
        self._last = (key, (V0, V1, U0, U1), img)  # _expose leaves it as it is
        out[V0:V1, U0:U1] = _expose(img, noise, rng, self._normals(img.size, rng), optics.gamma)
        return out

    def _cover(
        self, plate: Plate, T: Transform, box: tuple[int, int, int, int]
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Coverage (0..1) and grey level of ``plate`` over pixel ``box``.

        The box is cut into TILE x TILE tiles. A tile whose centre lies more than
        ``_UNIFORM_PX`` pixels from every boundary is uniform (coverage 0 or 1, one level)
        and filled from its centre; only the other tiles are computed pixel by pixel: compiled
        for plain and disc plates (:mod:`activesurv_sim.render_kernels`), in numpy for boards.
        """
        f = _PlateFrame(plate, T, self.camera)
        if plate.pattern is Pattern.CHECKER:
            return self._cover_arrays(f, box)
        disc = plate.pattern is Pattern.DISC
        M, p = f.kernel_parameters()
        return kernels.cover(self._rays32, np.array(box), M, p, disc, TILE, _UNIFORM_PX32)

    def _cover_arrays(
        self, f: _PlateFrame, box: tuple[int, int, int, int]
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """:meth:`_cover` in numpy array operations (any plate; the reference)."""
        u0, u1, v0, v1 = box
        hb, wb = v1 - v0, u1 - u0
        ty, tx = -(-hb // TILE), -(-wb // TILE)
        cv = np.minimum(np.arange(ty) * TILE + TILE // 2, hb - 1) + v0
        cu = np.minimum(np.arange(tx) * TILE + TILE // 2, wb - 1) + u0
        c_cov, c_lev, c_near = f.fields(self._rays32[cv[:, None], cu[None, :]].reshape(-1, 3))
        uniform = (c_near > _UNIFORM_PX).reshape(ty, tx)

        def tiles(x: NDArray[np.float32]) -> NDArray[np.float32]:
            full = np.repeat(np.repeat(x.reshape(ty, tx), TILE, axis=0), TILE, axis=1)
            return np.ascontiguousarray(full[:hb, :wb])

        cov, lev = tiles(c_cov), tiles(c_lev)
        ti, tj = np.nonzero(~uniform)
        if ti.size:
            # Pixel indices of the boundary tiles (integer gathers: no boolean masks).
            k = np.arange(TILE)
            vv = (ti[:, None, None] * TILE + k[None, :, None]) + np.zeros((1, 1, TILE), int)
            uu = (tj[:, None, None] * TILE + k[None, None, :]) + np.zeros((1, TILE, 1), int)
            keep = (vv < hb) & (uu < wb)
            vv, uu = vv[keep], uu[keep]
            cov[vv, uu], lev[vv, uu], _ = f.fields(self._rays32[vv + v0, uu + u0])
        return cov, lev

    def _normals(self, n: int, rng: np.random.Generator) -> NDArray[np.float32]:
        """``n`` standard normal draws: a window at a random offset of a pool drawn once."""
        extra = 64 * self.camera.width
        size = self.camera.height * self.camera.width + extra
        if self._pool_normals is None:
            self._pool_normals = rng.standard_normal(size, dtype=np.float32)
        off = int(rng.integers(0, size - n + 1))
        return self._pool_normals[off : off + n]

    def _background(
        self, level: float, noise: SensorNoise, rng: np.random.Generator, gamma: float = 1.0
    ) -> NDArray[np.uint8]:
        """A noisy uniform frame: a window at a random offset of a pool drawn once."""
        h, w = self.camera.height, self.camera.width
        key = (float(level), noise.electrons_per_level, noise.read_noise, float(gamma))
        pool = self._pools.get(key)
        extra = 64 * w
        if pool is None:
            flat = np.full(h * w + extra, level, dtype=np.float32)
            pool = _expose(flat, noise, rng, None, gamma)
            if len(self._pools) >= 4:  # a camera has one exposure: a few levels at most
                self._pools.clear()
            self._pools[key] = pool
        off = int(rng.integers(0, extra + 1))
        return pool[off : off + h * w].reshape(h, w).copy()

    # -- supersample (reference) ---------------------------------------------------------
    def _supersampled(
        self,
        T_world_camera: Transform,
        scene: Scene,
        noise: SensorNoise,
        boxes: list[tuple[int, tuple[int, int, int, int]]],
    ) -> Array:
        """The noise-free frame (float64), edges supersampled."""
        cam = self.camera
        h, w = cam.height, cam.width
        origin, R = T_world_camera.t, T_world_camera.R
        img: Array = np.full((h, w), scene.background, dtype=np.float64)
        lab = np.zeros((h, w), dtype=np.int64)
        if not boxes:
            return img
        u0 = min(b[0] for _, b in boxes)
        u1 = max(b[1] for _, b in boxes)
        v0 = min(b[2] for _, b in boxes)
        v1 = max(b[3] for _, b in boxes)
        depth = np.full((h, w), np.inf)
        for i, (bu0, bu1, bv0, bv1) in boxes:
            # Each plate is tested only inside its own box; a depth buffer resolves overlaps.
            dirs = self._rays[bv0:bv1, bu0:bu1].reshape(-1, 3)
            shape = (bv1 - bv0, bu1 - bu0)
            d_sub = depth[bv0:bv1, bu0:bu1].reshape(-1).copy()
            l_sub = img[bv0:bv1, bu0:bu1].reshape(-1).copy()
            k_sub = lab[bv0:bv1, bu0:bu1].reshape(-1).copy()
            _shade(scene, origin, dirs, i, d_sub, l_sub, k_sub, rotation=R)
            depth[bv0:bv1, bu0:bu1] = d_sub.reshape(shape)
            img[bv0:bv1, bu0:bu1] = l_sub.reshape(shape)
            lab[bv0:bv1, bu0:bu1] = k_sub.reshape(shape)

        # Edge pixels: any 8-neighbour with another label. Re-render with s x s rays.
        s = noise.supersample
        if s > 1:
            sub_lab = lab[v0:v1, u0:u1].astype(np.float32)
            kernel = np.ones((3, 3), np.uint8)
            edge = cv2.dilate(sub_lab, kernel) != cv2.erode(sub_lab, kernel)
            ev, eu = np.nonzero(edge)
            if ev.size:
                ev, eu = ev + v0, eu + u0
                offs = (np.arange(s) + 0.5) / s - 0.5
                ou, ov = np.meshgrid(offs, offs)
                sub = np.column_stack(
                    [
                        (eu[:, None] + ou.ravel()[None, :]).ravel(),
                        (ev[:, None] + ov.ravel()[None, :]).ravel(),
                    ]
                )
                sub_level, _ = _shade(scene, origin, cam.rays(sub), rotation=R)
                img[ev, eu] = sub_level.reshape(-1, s * s).mean(axis=1)
        return img


def _frame_key(
    T: Transform, scene: Scene, noise: SensorNoise, optics: FrameOptics
) -> tuple[object, ...]:
    """Everything a coverage frame depends on before the sensor's noise, exactly."""
    plates = tuple(
        (
            p.center.tobytes(),
            p.normal.tobytes(),
            p.x_axis.tobytes(),
            p.half_size,
            p.pattern,
            p.radius,
            p.squares,
            p.square_size,
            p.plate_level,
            p.mark_level,
            p.one_sided,
        )
        for p in scene.plates
    )
    return (
        np.asarray(T.R).tobytes(),
        np.asarray(T.t).tobytes(),
        plates,
        scene.background,
        scene.ambient_gradient,
        noise.blur_sigma,
        optics,
    )


TILE = 8
_UNIFORM_PX = 1.5 * TILE  # > the farthest pixel of a tile from its centre, with margin
_UNIFORM_PX32 = np.float32(_UNIFORM_PX)


class _PlateFrame:
    """Per-ray plate coordinates and their pixel gradients, for one plate and camera pose."""

    def __init__(self, plate: Plate, T: Transform, camera: CameraModel) -> None:
        self.plate = plate
        axes = np.column_stack([plate.normal, plate.x_axis, plate.y_axis])
        # camera-frame ray -> components along (normal, x_axis, y_axis)
        self.M = (T.R.T @ axes).astype(np.float32)
        rel0 = T.t - plate.center
        self.n0 = np.float32(rel0 @ plate.normal)
        self.a0 = np.float32(rel0 @ plate.x_axis)
        self.b0 = np.float32(rel0 @ plate.y_axis)
        self.fx_inv = np.float32(1.0 / camera.fx)
        self.fy_inv = np.float32(1.0 / camera.fy)

    def kernel_parameters(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """``M`` and the scalars :func:`activesurv_sim.render_kernels.cover` takes."""
        pl = self.plate
        scalars = (self.n0, self.a0, self.b0, self.fx_inv, self.fy_inv, *pl.half_size)
        p = np.array([*scalars, pl.radius, pl.plate_level, pl.mark_level], dtype=np.float32)
        return np.ascontiguousarray(self.M), p

    def fields(
        self, rays: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
        """For rays (N, 3): coverage, grey level and the distance in pixels to the nearest
        boundary (plate edge, disc rim or checker line)."""
        M, plate = self.M, self.plate
        comps = rays @ M
        c0, c1, c2 = comps[:, 0], comps[:, 1], comps[:, 2]
        with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
            inv = np.float32(1.0) / c0
            t = -self.n0 * inv
            valid = np.isfinite(t) & (t > 0.0)
            t = np.where(valid, t, np.float32(0.0))
            ka = np.where(valid, c1 * inv, np.float32(0.0))
            kb = np.where(valid, c2 * inv, np.float32(0.0))
        a = np.where(valid, self.a0 + t * c1, _FAR)
        b = np.where(valid, self.b0 + t * c2, _FAR)
        # d(plate coordinate)/d(pixel): a = a0 - n0 c1 / c0 with dc_j/du = M[0, j] / fx (the
        # rays' own distortion changes this by well under 1 %, which only widens an edge ramp).
        tu, tv = t * self.fx_inv, t * self.fy_inv
        dau = tu * (M[0, 1] - ka * M[0, 0])
        dav = tv * (M[1, 1] - ka * M[1, 0])
        dbu = tu * (M[0, 2] - kb * M[0, 0])
        dbv = tv * (M[1, 2] - kb * M[1, 0])
        eps = np.float32(1e-12)
        ga = np.sqrt(dau * dau + dav * dav) + eps  # metres of a per pixel, across a line a=c
        gb = np.sqrt(dbu * dbu + dbv * dbv) + eps
        sa = (np.abs(a) - np.float32(plate.half_size[0])) / ga
        sb = (np.abs(b) - np.float32(plate.half_size[1])) / gb
        cov = np.where(valid, _ramp(sa) * _ramp(sb), np.float32(0.0))
        near = np.where(valid, np.minimum(np.abs(sa), np.abs(sb)), np.float32(0.0))
        lo, hi = np.float32(plate.plate_level), np.float32(plate.mark_level)
        if plate.pattern is Pattern.DISC:
            rho = np.sqrt(a * a + b * b) + eps
            gx = (a * dau + b * dbu) / rho
            gy = (a * dav + b * dbv) / rho
            sd = (rho - np.float32(plate.radius)) / (np.sqrt(gx * gx + gy * gy) + eps)
            mark = _ramp(sd)
            near = np.minimum(near, np.abs(sd))
        elif plate.pattern is Pattern.CHECKER:
            mark, line = _checker(plate, a, b, ga, gb)
            near = np.minimum(near, line)
        else:
            mark = np.zeros_like(a)
        level = lo + (hi - lo) * mark
        return cov.astype(np.float32), level.astype(np.float32), near.astype(np.float32)


def _ramp(signed_px: NDArray[np.float32]) -> NDArray[np.float32]:
    """Fraction of a pixel inside a boundary whose signed distance (in pixels) is given."""
    return np.asarray(
        np.clip(np.float32(0.5) - signed_px, np.float32(0.0), np.float32(1.0)), dtype=np.float32
    )


def _checker(
    plate: Plate,
    a: NDArray[np.float32],
    b: NDArray[np.float32],
    ga: NDArray[np.float32],
    gb: NDArray[np.float32],
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Dark-square coverage of a checkerboard (separable ramps across the grid lines), and
    the distance in pixels to the nearest grid line or board edge."""
    cols, rows = plate.squares
    s = np.float32(plate.square_size)

    def axis(
        x: NDArray[np.float32], g: NDArray[np.float32], n: int
    ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
        u = x / s + np.float32(n / 2)
        cell = np.clip(np.floor(u), 0, n - 1)
        sign = np.where(cell % 2 == 0, np.float32(1.0), np.float32(-1.0))
        edge = (np.abs(x) - np.float32(n / 2) * s) / g
        if n > 1:  # distance to the nearest interior grid line, in pixels
            line = np.abs(u - np.clip(np.rint(u), 1, n - 1)) * s / g
        else:
            line = np.full_like(u, np.inf)
        near = np.minimum(np.float32(2.0) * line, np.float32(1.0))
        return (sign * near).astype(np.float32), _ramp(edge), np.minimum(line, np.abs(edge))

    xa, ia, la = axis(a, ga, cols)
    xb, ib, lb = axis(b, gb, rows)
    dark = np.float32(0.5) * (1.0 + xa * xb) * ia * ib
    return dark.astype(np.float32), np.minimum(la, lb).astype(np.float32)


def _expose(
    img: NDArray[np.float32],
    noise: SensorNoise,
    rng: np.random.Generator,
    normals: NDArray[np.float32] | None = None,
    gamma: float = 1.0,
) -> NDArray[np.uint8]:
    """Shot noise (Poisson in electrons, here >1000 e-: Gaussian) and read noise on the linear
    levels, then the camera's response (``gamma``), quantised.

    ``normals``: standard normal draws to use (as many as pixels), else drawn from ``rng``.
    """
    if noise.electrons_per_level > 0.0 or noise.read_noise > 0.0:
        var = np.maximum(img, np.float32(0.0))
        var *= np.float32(noise.electrons_per_level and 1.0 / noise.electrons_per_level)
        var += np.float32(noise.read_noise**2)
        z = rng.standard_normal(img.shape, dtype=np.float32) if normals is None else normals
        img = np.asarray(
            cv2.add(img, cv2.multiply(cv2.sqrt(var), z.reshape(img.shape))), dtype=np.float32
        )
    img = _encode(img, gamma)
    # Saturating, rounding conversion (negative levels are clipped to 0 first).
    return np.asarray(cv2.convertScaleAbs(np.maximum(img, np.float32(0.0))), dtype=np.uint8)


def render(
    camera: CameraModel,
    T_world_camera: Transform,
    scene: Scene,
    noise: SensorNoise | None = None,
    rng: np.random.Generator | None = None,
    optics: FrameOptics = IDEAL_OPTICS,
) -> NDArray[np.uint8]:
    """Render an 8-bit grey image of ``scene`` seen by ``camera`` at ``T_world_camera``.

    Args:
        camera: intrinsics (distortion is honoured).
        T_world_camera: pose of the camera optical frame in the world.
        scene: plates and background.
        noise: image formation; ``None`` for the defaults, ``SensorNoise(0, 0, 0)`` for an ideal
            noise-free (but still anti-aliased and quantised) image.
        rng: random generator for the noise (seed it for reproducible images).
        optics: depth of field, motion streak, exposure and response of this frame (default:
            a pinhole's: none).

    Returns:
        (height, width) uint8 image. For many frames of one camera keep a :class:`Renderer`.
    """
    return Renderer(camera).render(T_world_camera, scene, noise, rng, optics)


def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> Transform:
    """Pose of an optical frame at ``eye`` looking at ``target`` (z forward, y down, x right).

    Raises:
        RenderError: if ``eye`` and ``target`` coincide or the view is along ``up``.
    """
    e, t = as_vector3(eye, 'eye'), as_vector3(target, 'target')
    if np.linalg.norm(t - e) < 1e-12:
        raise RenderError('eye and target coincide')
    z = unit(t - e)
    x = cross3(z, as_vector3(up, 'up'))
    if np.linalg.norm(x) < 1e-9:
        raise RenderError('viewing direction is parallel to up; pick another up vector')
    x = unit(x)
    y = cross3(z, x)
    return Transform(np.column_stack([x, y, z]), e)
