"""In-process node test: the simulated table's state of a demand instant waits
``instant_state_delay`` past the instant (the cameras image meanwhile), keeps its order before
the grid's next state, and goes out at a stop."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest
from rclpy.parameter import Parameter

from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import sec_to_time
from activesurv_sim.xy_table_node import XYTableNode

pytestmark = pytest.mark.node  # in-process rclpy nodes


def _table(delay: float, rate: float = 10.0) -> XYTableNode:
    return XYTableNode(
        parameter_overrides=[
            Parameter('publish_rate', value=rate),
            Parameter('publish_phase', value=0.5 / rate),  # states half a period off instants
            Parameter('instant_ticks', value=False),
            Parameter('instant_state_delay', value=delay),
        ]
    )


def _stamp(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def _stamps_heard(peer: Any) -> list[float]:
    """The stamps of the object states ``peer`` hears, in the order it hears them."""
    from activesurv_interfaces.msg import ObjectState

    heard: list[float] = []
    peer.create_subscription(
        ObjectState, topics.OBJECT_STATE, lambda m: heard.append(_stamp(m)), qos.STATE
    )
    return heard


def _requester(
    table: XYTableNode, peer: Any, spin_until: Callable[..., bool]
) -> Callable[[float], None]:
    """Once the table's time runs and it hears capture requests: ask for a demand instant."""
    from activesurv_interfaces.msg import CaptureRequest

    req = peer.create_publisher(CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS)
    assert spin_until(
        [table, peer],
        lambda: table._wall0 is not None and req.get_subscription_count() >= 1,
        timeout=20.0,
    )
    return lambda t: req.publish(
        CaptureRequest(demand_instant=sec_to_time(t), camera_ids=['cam1'])
    )


@pytest.mark.parametrize('delay', [0.03, 0.2, 0.0])
def test_an_instants_state_waits_its_delay_and_keeps_its_order(
    rclpy_context: Any, spin_until: Callable[..., bool], delay: float
) -> None:
    from activesurv_interfaces.msg import ObjectState

    table = _table(delay)
    peer = rclpy_context.create_node('table_instants_test_peer')
    heard: list[tuple[float, float]] = []  # (stamp, simulated time heard)
    try:

        def on_state(msg: ObjectState) -> None:
            assert table._wall0 is not None
            heard.append((_stamp(msg), table.sim_time()))

        peer.create_subscription(ObjectState, topics.OBJECT_STATE, on_state, qos.STATE)
        request = _requester(table, peer, spin_until)
        # An instant on the tenths: the grid's states are 50 ms either side of it.
        t = math.ceil((table.sim_time() + 0.4) * 10.0) / 10.0
        request(t)
        assert spin_until(
            [table, peer],
            lambda: any(s > t + 0.04 for s, _ in heard),  # the grid's next (its tick's time)
            timeout=10.0,
        ), f'no state after {t:.2f} s: {heard}'
        stamps = [s for s, _ in heard]
        assert stamps == sorted(stamps), 'states out of order'
        at = [h for s, h in heard if abs(s - t) < 1e-6]
        assert len(at) == 1, f'the instant {t:.2f} s has no state of its own: {stamps}'
        if delay > 0.0:
            # Never before its delay (and with a long one, sent as the grid's next state goes).
            assert at[0] >= t + min(delay, 0.05) - 0.005, f'state of {t} heard at {at[0]:.4f}'
    finally:
        table.destroy_node()
        peer.destroy_node()


def test_a_stop_sends_the_instants_state_still_waiting(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    table = _table(0.3, rate=1.0)  # the grid's states at .5 s: far from the instant
    peer = rclpy_context.create_node('table_instants_stop_peer')
    try:
        heard = _stamps_heard(peer)
        request = _requester(table, peer, spin_until)
        t = float(math.ceil(table.sim_time() + 0.7))
        request(t)
        assert spin_until([table, peer], lambda: table.sim_time() > t + 0.05, timeout=10.0)
        assert not any(abs(s - t) < 1e-6 for s in heard), 'sent before its delay'
        assert table.instants.waiting() == [t]  # passed, waiting
        table.flush()  # the console script's on_stop, the container's flush pass
        assert spin_until([table, peer], lambda: any(abs(s - t) < 1e-6 for s in heard), 5.0)
    finally:
        table.destroy_node()
        peer.destroy_node()


def test_two_instants_close_together_keep_their_order(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """Two objects' instants 10 ms apart, each state waiting 30 ms: the earlier goes first."""
    table = _table(0.03)
    peer = rclpy_context.create_node('table_instants_pair_peer')
    try:
        heard = _stamps_heard(peer)
        request = _requester(table, peer, spin_until)
        t = math.ceil((table.sim_time() + 0.4) * 10.0) / 10.0
        for when in (t, t + 0.01):
            request(when)
        assert spin_until([table, peer], lambda: any(s > t + 0.04 for s in heard), 10.0)
        mine = [s for s in heard if t - 1e-6 < s < t + 0.02]
        assert len(mine) == 2, f'states of {t:.2f} and {t + 0.01:.2f} s: {heard}'
        assert heard == sorted(heard), f'states out of order: {heard}'
    finally:
        table.destroy_node()
        peer.destroy_node()


def test_the_states_around_a_requested_instant_are_relayed_and_no_others(
    rclpy_context: Any, spin_until: Callable[..., bool]
) -> None:
    """``sim/instant_object_state``: two grid states before the instant, its own, one after,
    each once; a request for an instant whose window has begun gets its first states again."""
    from activesurv_interfaces.msg import ObjectState

    table = _table(0.0)
    peer = rclpy_context.create_node('table_instants_relay_peer')
    relayed: list[float] = []
    try:
        every = _stamps_heard(peer)
        peer.create_subscription(
            ObjectState,
            topics.INSTANT_OBJECT_STATE,
            lambda m: relayed.append(_stamp(m)),
            qos.EVENTS,
        )
        request = _requester(table, peer, spin_until)
        matched = lambda: table._relay_pub.get_subscription_count() >= 1  # noqa: E731
        assert spin_until([table, peer], matched, timeout=10.0)
        t1 = math.ceil((table.sim_time() + 0.5) * 10.0) / 10.0
        request(t1)
        assert spin_until([table, peer], lambda: any(s > t1 + 0.01 for s in relayed), 10.0)
        # The second is asked when its window has begun: the state 0.15 s before it has gone.
        assert spin_until([table, peer], lambda: table.sim_time() > t1 + 0.37, 10.0)
        t2 = round(t1 + 0.5, 6)
        request(t2)
        assert spin_until([table, peer], lambda: any(s > t2 + 0.01 for s in relayed), 10.0)
        want = [t1 - 0.15, t1 - 0.05, t1, t1 + 0.05, t2 - 0.15, t2 - 0.05, t2, t2 + 0.05]
        assert len(relayed) == len(want), f'relayed {relayed}'
        assert all(abs(a - b) < 0.02 for a, b in zip(sorted(relayed), want, strict=True)), (
            f'relayed {sorted(relayed)}, want {want}'
        )
        assert len(every) > len(relayed) + 5  # object_state keeps every state
        assert all(any(abs(s - r) < 1e-9 for s in every) for r in relayed)  # the same states
    finally:
        table.destroy_node()
        peer.destroy_node()
