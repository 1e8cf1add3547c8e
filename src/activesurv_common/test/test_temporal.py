"""Temporal calibration: the delay of synthetic frames of a target swept back and forth."""

from __future__ import annotations

import numpy as np
import pytest

from activesurv_common.temporal import TemporalFitError, fit_delay


def _sweep(delay: float, jitter: float, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    # The table: back and forth over 60 mm at 20 and 40 mm/s, reported at 20 Hz.
    t = np.arange(0.0, 12.0, 0.05)
    x = 0.03 * np.sin(2 * np.pi * t / 6.0) + 0.02 * np.sin(2 * np.pi * t / 2.0)
    frames = np.arange(0.3, 11.7, 1 / 30)  # exposures
    xe = np.interp(frames, t, x)
    uv = np.c_[320 + 9000 * xe, 240 - 2500 * xe] + rng.normal(0, 0.05, (len(frames), 2))
    stamps = frames + delay + rng.normal(0, jitter, len(frames))
    return stamps, uv, t, x


@pytest.mark.parametrize(('delay', 'seed'), [(0.005, 1), (0.02, 2), (0.047, 3), (0.06, 4)])
def test_the_delay_is_found_within_half_a_millisecond(delay: float, seed: int) -> None:
    stamps, uv, t, x = _sweep(delay, 0.002, seed)
    fit = fit_delay(stamps, uv, t, x)
    assert fit.delay == pytest.approx(delay, abs=5e-4)
    assert fit.jitter == pytest.approx(0.002, rel=0.35)
    assert fit.samples > 300


def test_a_static_offset_of_the_image_does_not_move_the_delay() -> None:
    stamps, uv, t, x = _sweep(0.03, 0.001, 5)
    a = fit_delay(stamps, uv, t, x).delay
    b = fit_delay(stamps, uv + [12.0, -7.0], t, x).delay
    assert a == pytest.approx(b, abs=1e-5)


def test_a_still_table_or_too_few_frames_is_refused() -> None:
    stamps, uv, t, x = _sweep(0.03, 0.001, 6)
    with pytest.raises(TemporalFitError, match='did not move'):
        fit_delay(stamps, uv, t, np.zeros_like(x))
    with pytest.raises(TemporalFitError, match='at least 10'):
        fit_delay(stamps[:5], uv[:5], t, x)
