"""The compiled coverage of a plate (``render_kernels.cover``) is the array code's, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.camera_model import dynamic_camera
from activesurv_common.geometry import Transform
from activesurv_sim.render import Plate, Renderer, _PlateFrame, look_at


def _views(n: int, seed: int) -> list[tuple[Plate, Transform]]:
    """Plates with a disc or plain, seen from 0.3-1.5 m at up to 80 deg off their normal, near
    the image border and partly out of it, and a few whose plane passes behind the camera."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        centre = rng.uniform(-0.05, 0.05, 3)
        tilt = np.radians(rng.uniform(0.0, 80.0))
        side = np.cross(normal, rng.normal(size=3))
        side /= np.linalg.norm(side)
        view = np.cos(tilt) * normal + np.sin(tilt) * side
        eye = centre + rng.uniform(0.3, 1.5) * view
        aim = centre + rng.uniform(-0.08, 0.08, 3)  # off centre: at the border, cut by it
        plate = (
            Plate.disc(centre, normal, rng.uniform(0.005, 0.03), 0.06)
            if k % 3
            else Plate(centre, normal, side, (0.04, 0.06))
        )
        if k % 7 == 0:  # the camera in the plate's box: its plane straddles the camera
            eye = centre + 0.02 * side + 0.01 * normal
        out.append((plate, look_at(eye, aim)))
    return out


def _matmul_as_the_kernel() -> bool:
    """Whether numpy's float32 matrix product accumulates as the kernel does (the first
    product, then fused multiply-adds: OpenBLAS's kernels on this machine). Elsewhere the two
    differ in the last bit of a few pixels' coverage."""
    rng = np.random.default_rng(0)
    r, m = (
        rng.normal(size=(4096, 3)).astype(np.float32),
        rng.normal(size=(3, 3)).astype(np.float32),
    )
    acc = (r[:, :1] * m[0]).astype(np.float64)
    for k in (1, 2):
        acc = (r[:, k : k + 1].astype(np.float64) * m[k] + acc.astype(np.float32)).astype(
            np.float32
        )
    return bool(np.array_equal(r @ m, acc.astype(np.float32)))


@pytest.mark.parametrize('seed', [1, 2])
def test_the_compiled_cover_is_the_array_codes_bit_for_bit(seed: int) -> None:
    renderer = Renderer(dynamic_camera('cam1'))
    boundary, exact = 0, _matmul_as_the_kernel()
    for plate, T in _views(60, seed):
        box = renderer._plate_box(plate, T)
        if box is None:
            continue
        cov, lev = renderer._cover(plate, T, box)
        cov0, lev0 = renderer._cover_arrays(_PlateFrame(plate, T, renderer.camera), box)
        assert cov.dtype == np.float32
        assert lev.dtype == np.float32
        if exact:
            np.testing.assert_array_equal(cov, cov0)
            np.testing.assert_array_equal(lev, lev0)
        else:
            np.testing.assert_allclose(cov, cov0, rtol=0.0, atol=1e-4)
            np.testing.assert_allclose(lev, lev0, rtol=0.0, atol=0.05)
        boundary += int(np.count_nonzero((cov0 > 0) & (cov0 < 1)))
    assert boundary > 10_000  # edges were drawn, not only uniform tiles
