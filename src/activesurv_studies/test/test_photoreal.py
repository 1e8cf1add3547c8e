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


def test_ours_on_the_stored_set_against_plain_opencv(stored: tuple[list, dict]) -> None:  # type: ignore[type-arg]
    views, _ = stored
    ours = summary([measure_ours(v) for v in views])
    cv = summary([measure_opencv(v) for v in views])
    # Measured (docs/performance.md): ours 0.02-0.05 mm median in the still, in-focus cases
    # (0.06-0.09 mm while the edges were measured at the boundary pixels' angles), 0.07 mm
    # defocused, 0.06 / 0.13 mm (median / p90) under 11-26 px of motion blur (0.27 / 0.56 mm
    # while every edge of a streaked marker had the longest ramp's window); plain OpenCV about
    # 1 mm (tens of mm under motion blur).
    for case in ('nominal', 'glossy', 'side_light', 'bright_table', 'defocus'):
        assert ours[case]['detected'] == 1.0, case
    for case in ('nominal', 'glossy', 'side_light', 'bright_table', 'dim'):
        assert ours[case]['median_mm'] <= 0.08, (case, ours[case])  # issue 33: nominal <= 0.08
    assert ours['defocus']['median_mm'] <= 0.25, ours['defocus']
    assert ours['motion_blur']['median_mm'] <= 0.2, ours['motion_blur']  # issue 33's goals
    assert ours['all']['median_mm'] <= 0.1, ours['all']
    assert ours['all']['p90_mm'] <= 0.4, ours['all']
    assert ours['motion_blur']['p90_mm'] <= 0.4, ours['motion_blur']
    # Beside a second disc the edges searched from the coarse boundary were pixels off in one
    # view (10.9 mm); measured again centred on each edge, every view is within a millimetre.
    assert ours['distractor']['p90_mm'] <= 1.0, ours['distractor']
    # Every view measured, given the predicted position: the two whose disc runs into a bright
    # bar in front of it (refused as one blob touching the border) from the arc that shows.
    assert ours['all']['detected'] == 1.0, ours['all']
    assert 3.0 * ours['all']['median_mm'] < cv['all']['median_mm']


def test_a_missing_set_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(PhotorealError, match=r'truth\.json'):
        load_set(tmp_path)
    (tmp_path / 'truth.json').write_text('{"images": [{"image": "gone.png"}]}')
    with pytest.raises(PhotorealError, match=r'gone\.png: missing'):
        load_set(tmp_path)
    (tmp_path / 'truth.json').write_text('{"images": []}')
    with pytest.raises(PhotorealError, match='no images'):
        load_set(tmp_path)
