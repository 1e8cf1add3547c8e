"""Run time 0 of a hardware run: far enough after the launch for the nodes to start on the
machine at hand (``hardware_graph.start_margin``)."""

from __future__ import annotations

import pytest

from activesurv_bringup.experiments.hardware_graph import START_MARGIN, start_margin

pytestmark = pytest.mark.cross


def test_a_small_machine_waits_longer_for_the_same_nodes() -> None:
    # The paper's rig: 16 node processes. Two cores needed ~31 s beside the lab (docs/hardware.md).
    assert start_margin(16, cores=2) >= 32.0
    assert start_margin(16, cores=4) == START_MARGIN
    assert start_margin(16, cores=64) == START_MARGIN  # never below the floor
    assert start_margin(40, cores=2) > start_margin(16, cores=2)  # more nodes, more time


def test_the_margin_uses_this_machines_cores_by_default() -> None:
    assert start_margin(16) >= START_MARGIN
