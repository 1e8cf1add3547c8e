"""An orchestrator's node leaves nothing behind on the domain when its ``with`` block ends.

Stage goals are latched (transient local): a goal publisher that outlived commissioning went
on serving the last goal of each stage to every stage that started later on the same domain,
and the simulated stages of the runs after it (the fidelity bench runs them one after the
other on one domain) moved to commissioning's poses before their first plan. The stages now
also refuse such a goal by its stamp (``test_stage_nodes.py``)."""

from __future__ import annotations

import time
from typing import Any

import pytest

pytestmark = pytest.mark.node


def test_a_finished_commissioner_serves_no_latched_goal(rclpy_context: Any) -> None:
    from activesurv_bringup.rig.commission import Commissioner
    from activesurv_common.ros import qos, topics
    from activesurv_dispatch.sensors import load_setup
    from activesurv_interfaces.msg import StageGoal

    heard: list[StageGoal] = []
    with Commissioner(load_setup(motion='fast'), ['cam1']) as com:
        com.send_goal('cam1', ['cam1_x', 'cam1_yaw'], [0.1, 0.2])
        # The goal is served while it lives: a late listener hears it.
        early = rclpy_context.create_node('early_stage_stand_in')
        early.create_subscription(StageGoal, topics.goal('cam1'), heard.append, qos.GOAL)
        deadline = time.monotonic() + 10.0
        while not heard and time.monotonic() < deadline:
            com.spin(0.05)
            rclpy_context.spin_once(early, timeout_sec=0.05)
        early.destroy_node()
        assert heard, 'the latched goal never reached a listener while the commissioner lived'
    assert rclpy_context.ok()  # not its to shut: the session's rclpy was started before it
    late: list[StageGoal] = []
    node = rclpy_context.create_node('late_stage_stand_in')
    try:
        node.create_subscription(StageGoal, topics.goal('cam1'), late.append, qos.GOAL)
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            rclpy_context.spin_once(node, timeout_sec=0.05)
        assert late == [], 'a closed commissioner still serves its last goal'
    finally:
        node.destroy_node()
