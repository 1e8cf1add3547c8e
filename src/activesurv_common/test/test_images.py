"""Every encoding a camera driver publishes becomes the grey image the imager measures on."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.errors import ImageFormatError
from activesurv_common.images import ENCODINGS, LUMA_RGB, bayer_to_gray, to_gray

H, W = 48, 64


def scene(seed: int = 0) -> np.ndarray:
    """A smooth colour scene (h, w, 3) in 0..255 with a bright disc."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    base = 60 + 20 * np.sin(xx / 9.0)[..., None] * rng.uniform(0.5, 1.0, 3)
    disc = ((xx - 31.3) ** 2 + (yy - 22.7) ** 2) < 12.0**2
    img = base + 150 * disc[..., None] * np.array([1.0, 0.9, 0.8])
    return np.clip(img, 0, 255)


def luma(rgb: np.ndarray) -> np.ndarray:
    return rgb @ np.array(LUMA_RGB)


def mosaic(rgb: np.ndarray, order: str) -> np.ndarray:
    """The Bayer mosaic of ``order`` (e.g. 'rggb': row 0 R G, row 1 G B)."""
    index = {'r': 0, 'g': 1, 'b': 2}
    out = np.empty(rgb.shape[:2])
    for k, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        out[dy::2, dx::2] = rgb[dy::2, dx::2, index[order[k]]]
    return out.astype(np.uint8)


def centroid(gray: np.ndarray) -> np.ndarray:
    w = np.clip(gray.astype(np.float64) - 140.0, 0.0, None)
    yy, xx = np.mgrid[0 : gray.shape[0], 0 : gray.shape[1]]
    return np.array([(w * xx).sum(), (w * yy).sum()]) / w.sum()


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8', 'rgba8', 'bgra8'])
def test_colour_is_luma(encoding: str) -> None:
    rgb = scene().astype(np.uint8)
    px = rgb if encoding.startswith('rgb') else rgb[:, :, ::-1]
    if encoding.endswith('a8'):
        px = np.concatenate([px, np.full((H, W, 1), 255, np.uint8)], axis=2)
    n = px.shape[2]
    gray = to_gray(px.tobytes(), W, H, W * n, encoding)
    assert np.abs(gray.astype(float) - luma(rgb.astype(float))).max() <= 1.0


@pytest.mark.parametrize('order', ['rggb', 'bggr', 'gbrg', 'grbg'])
def test_bayer_of_any_order_is_centred_luma(order: str) -> None:
    rgb = scene(1)
    m = mosaic(rgb, order)
    gray = to_gray(m.tobytes(), W, H, W, f'bayer_{order}8')
    assert gray.shape == (H, W)  # full resolution: the intrinsics still hold
    # (R + 2G + B) / 4 of the smoothed scene: within a few levels away from the disc's edge.
    expected = (rgb[..., 0] + 2 * rgb[..., 1] + rgb[..., 2]) / 4.0
    yy, xx = np.mgrid[0:H, 0:W]
    inner = np.abs(np.hypot(xx - 31.3, yy - 22.7) - 12.0) > 2.5  # away from the disc's rim
    assert np.abs(gray.astype(float) - expected)[inner].max() < 4.0
    # The disc's centre does not move (no half-pixel shift of the demosaicing).
    truth = centroid(np.clip(expected, 0, 255).astype(np.uint8))
    assert np.linalg.norm(centroid(gray) - truth) < 0.2  # a half-pixel shift would be 0.5-0.7


def test_bayer_filter_is_the_same_as_explicit_weights() -> None:
    m = np.random.default_rng(2).integers(0, 256, (6, 8), dtype=np.uint8)
    g = bayer_to_gray(m)
    p = np.pad(m.astype(float), 1, mode='reflect')
    k = np.outer([1, 2, 1], [1, 2, 1]) / 16.0
    ref = np.array([[(p[y : y + 3, x : x + 3] * k).sum() for x in range(8)] for y in range(6)])
    assert np.abs(g - ref).max() <= 0.5 + 1e-9


@pytest.mark.parametrize('bits', [8, 10, 12, 16])
@pytest.mark.parametrize('bigendian', [False, True])
def test_mono16_keeps_the_significant_bits(bits: int, bigendian: bool) -> None:
    ref = scene(3)[..., 1].astype(np.uint8)
    v = (ref.astype(np.uint16) << (bits - 8)) | (1 << max(bits - 9, 0)) * (bits > 8)
    data = v.astype('>u2' if bigendian else '<u2').tobytes()
    gray = to_gray(data, W, H, 2 * W, 'mono16', bigendian)
    assert np.array_equal(gray, ref)


@pytest.mark.parametrize('encoding', ['yuv422', 'uyvy', 'yuv422_yuy2', 'yuyv'])
def test_yuv422_gives_its_y_samples(encoding: str) -> None:
    y = scene(4)[..., 0].astype(np.uint8)
    uv = np.full_like(y, 128)
    first, second = (uv, y) if encoding in ('yuv422', 'uyvy') else (y, uv)
    packed = np.stack([first, second], axis=2).reshape(H, 2 * W)
    assert np.array_equal(to_gray(packed.tobytes(), W, H, 2 * W, encoding), y)


def test_row_padding_is_dropped() -> None:
    y = scene(5)[..., 0].astype(np.uint8)
    padded = np.zeros((H, W + 8), np.uint8)
    padded[:, :W] = y
    assert np.array_equal(to_gray(padded.tobytes(), W, H, W + 8, 'mono8'), y)


@pytest.mark.parametrize(
    ('encoding', 'size', 'step', 'match'),
    [
        ('jpeg', H * W, W, 'unsupported image encoding'),
        ('mono8', H * W - 1, W, 'does not match'),
        ('mono16', H * W, W, 'does not match'),  # a step too small for 16 bits
        ('rgb8', H * W * 3, W * 3, None),
    ],
)
def test_bad_buffers_are_refused(encoding: str, size: int, step: int, match: str | None) -> None:
    data = bytes(size)
    if match is None:
        assert to_gray(data, W, H, step, encoding).shape == (H, W)
        return
    with pytest.raises(ImageFormatError, match=match):
        to_gray(data, W, H, step, encoding)


def test_every_listed_encoding_converts() -> None:
    for enc in ENCODINGS:
        per = {'mono16': 2, '16UC1': 2, 'rgb8': 3, 'bgr8': 3, 'rgba8': 4, 'bgra8': 4}.get(enc)
        per = per or (2 if 'yuv' in enc or enc in ('uyvy', 'yuyv') else 1)
        assert to_gray(bytes(H * W * per), W, H, W * per, enc).shape == (H, W), enc
