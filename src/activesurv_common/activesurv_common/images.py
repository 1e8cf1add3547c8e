"""Raw image buffers of the encodings camera drivers publish, as 8-bit grey (numpy only).

The imager measures the marker on grey levels; a ROS 2 camera driver publishes whatever its
sensor gives: ``mono8``, ``mono16`` (often 10 or 12 significant bits), colour (``rgb8``,
``bgr8``, ``rgba8``, ``bgra8``), the raw Bayer mosaic (``bayer_rggb8`` and the other three
orders) or packed YUV 4:2:2 (``yuv422``/``uyvy``: U Y V Y; ``yuv422_yuy2``/``yuyv``: Y U Y V).

* Colour: luma ``0.299 R + 0.587 G + 0.114 B``.
* Bayer: the separable ``[1 2 1] x [1 2 1] / 16`` filter. At every site of any of the four
  orders it weighs the mosaic's colours as ``R/4 + G/2 + B/4``, centred on the pixel (no
  half-pixel shift of the marker's centre, full resolution, so the intrinsics still hold).
* YUV 4:2:2: the Y samples (already luma at full resolution).
* 16-bit grey: scaled to 8 bits by the power of two that holds the frame's brightest pixel
  (a 12-bit sensor's 0..4095 becomes 0..255), so the significant bits are kept.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from activesurv_common.errors import ImageFormatError

Gray = NDArray[np.uint8]

CHANNELS = {
    'mono8': 1,
    '8UC1': 1,
    'mono16': 2,
    '16UC1': 2,
    'rgb8': 3,
    'bgr8': 3,
    'rgba8': 4,
    'bgra8': 4,
    'bayer_rggb8': 1,
    'bayer_bggr8': 1,
    'bayer_gbrg8': 1,
    'bayer_grbg8': 1,
    'yuv422': 2,
    'uyvy': 2,
    'yuv422_yuy2': 2,
    'yuyv': 2,
}
ENCODINGS = tuple(CHANNELS)
LUMA_RGB = (0.299, 0.587, 0.114)


def rows(data: bytes, width: int, height: int, step: int, encoding: str) -> NDArray[np.uint8]:
    """The image's bytes as (height, width * bytes per pixel), row padding removed.

    Raises:
        ImageFormatError: for an unknown encoding or a buffer that does not fit the header.
    """
    per_pixel = CHANNELS.get(encoding)
    if per_pixel is None:
        raise ImageFormatError(
            f'unsupported image encoding {encoding!r} (supported: {", ".join(ENCODINGS)})'
        )
    buf = np.frombuffer(data, dtype=np.uint8)
    if height <= 0 or width <= 0 or step < width * per_pixel or buf.size < height * step:
        raise ImageFormatError(
            f'image buffer of {buf.size} bytes does not match {width}x{height} {encoding} '
            f'step {step}'
        )
    return buf[: height * step].reshape(height, step)[:, : width * per_pixel]


def to_gray(
    data: bytes, width: int, height: int, step: int, encoding: str, bigendian: bool = False
) -> Gray:
    """An 8-bit grey image from a raw buffer of any of :data:`ENCODINGS`.

    Raises:
        ImageFormatError: for an unknown encoding or a buffer that does not fit the header.
    """
    r = rows(data, width, height, step, encoding)
    if CHANNELS[encoding] == 1 and not encoding.startswith('bayer_'):
        return np.ascontiguousarray(r)
    if encoding.startswith('bayer_'):
        return bayer_to_gray(r)
    if encoding in ('mono16', '16UC1'):
        return mono16_to_gray(r.reshape(height, width, 2), bigendian)
    if encoding in ('yuv422', 'uyvy'):
        return np.ascontiguousarray(r[:, 1::2])
    if encoding in ('yuv422_yuy2', 'yuyv'):
        return np.ascontiguousarray(r[:, 0::2])
    n = CHANNELS[encoding]
    px = r.reshape(height, width, n)[:, :, :3].astype(np.float32)
    w = LUMA_RGB if encoding.startswith('rgb') else LUMA_RGB[::-1]
    return np.clip(np.rint(px @ np.array(w, dtype=np.float32)), 0, 255).astype(np.uint8)


def mono16_to_gray(pairs: NDArray[np.uint8], bigendian: bool) -> Gray:
    """16-bit grey (as byte pairs, shape (h, w, 2)) to 8 bits, keeping the significant bits."""
    hi, lo = (pairs[:, :, 0], pairs[:, :, 1]) if bigendian else (pairs[:, :, 1], pairs[:, :, 0])
    v = (hi.astype(np.uint32) << 8) | lo.astype(np.uint32)
    bits = max(8, int(v.max()).bit_length())
    return (v >> (bits - 8)).astype(np.uint8)


def bayer_to_gray(mosaic: NDArray[np.uint8]) -> Gray:
    """Luma ``R/4 + G/2 + B/4`` of a Bayer mosaic of any order, centred, full resolution."""
    m = np.pad(mosaic.astype(np.uint16), 1, mode='reflect')
    h = m[:, :-2] + 2 * m[:, 1:-1] + m[:, 2:]
    v = h[:-2, :] + 2 * h[1:-1, :] + h[2:, :]
    out: Gray = ((v + 8) >> 4).astype(np.uint8)
    return out
