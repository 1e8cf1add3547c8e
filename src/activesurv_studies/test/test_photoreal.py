"""The stored physically based test set (issue 33, item 5): its camera convention, and our
imager against the plain OpenCV pipeline on it (no renderer needed: the images are stored)."""

from __future__ import annotations

from pathlib import Path

import pytest

from activesurv_studies.photoreal import (
    PhotorealError,
    load_set,
    measure_opencv,
    measure_ours,
    summary,
)

SET = Path(__file__).resolve().parents[3] / 'test' / 'data' / 'photoreal'


@pytest.fixture(scope='module')
def stored() -> tuple[list, dict]:  # type: ignore[type-arg]
    return load_set(SET)


def test_the_renders_follow_our_camera_convention(stored: tuple[list, dict]) -> None:  # type: ignore[type-arg]
    views, meta = stored
    assert meta['convention']['error_px'] < 0.01  # a disc's centroid against K's projection
    cases = {v.case for v in views}
    assert {'nominal', 'defocus', 'motion_blur', 'dim', 'distractor'} <= cases
    assert all(v.image.shape == (v.camera.height, v.camera.width) for v in views)


def test_every_view_is_measured_and_ours_beats_plain_opencv(stored: tuple[list, dict]) -> None:  # type: ignore[type-arg]
    views, _ = stored
    ours = summary([measure_ours(v) for v in views])
    cv = summary([measure_opencv(v) for v in views])
    assert ours['all']['detected'] == 1.0
    assert ours['all']['median_mm'] < cv['all']['median_mm']
    assert ours['all']['median_mm'] <= 0.1
    assert ours['nominal']['median_mm'] <= 0.1


def test_a_missing_set_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(PhotorealError, match=r'truth\.json'):
        load_set(tmp_path)
    (tmp_path / 'truth.json').write_text('{"images": [{"image": "gone.png"}]}')
    with pytest.raises(PhotorealError, match=r'gone\.png: missing'):
        load_set(tmp_path)
    (tmp_path / 'truth.json').write_text('{"images": []}')
    with pytest.raises(PhotorealError, match='no images'):
        load_set(tmp_path)
