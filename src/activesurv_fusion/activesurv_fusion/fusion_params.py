"""The ``fusion`` node's parameters (typed, checked at start and on every change)."""

from __future__ import annotations

from typing import Any

from activesurv_common.ros.parameters import Param


def _not_empty(v: Any) -> str | None:
    return None if str(v) else 'frame_id must not be empty'


PARAMS = (
    Param(
        'collect_timeout',
        2.0,
        's after a demand instant to wait for missing cameras',
        above=0.0,
        maximum=600.0,
    ),
    Param(
        'z_sigma',
        3.0,
        'abstract-sensor half-width in standard deviations (3: 99.74 %)',
        above=0.0,
        maximum=10.0,
    ),
    Param(
        'max_faulty',
        -1,
        'faulty cameras tolerated (k_f); -1: the largest k_f < k/2',
        minimum=-1,
        maximum=64,
    ),
    Param('frame_id', 'world', 'frame of the published poses', check=_not_empty),
    Param(
        'journal',
        '',
        'file of answered demand indices (kept across restarts); empty: none',
        read_only=True,
    ),
    Param(
        'announce_ready',
        False,
        'say on activesurv/ready when its inputs and the clock are matched (a graph run waits)',
    ),
)
