"""A node says when its topics are matched: the start of simulated time waits for it.

DDS matches a reader to a writer some time after both exist: on this two-core machine, while
nine processes start, up to a second or more after every node is up. A volatile input (the
overhead fixes) loses what is published before its reader is matched, and a predictor that
misses the first second of fixes has no track for the first demand. So each end of such a topic
calls :func:`announce_when_matched`: the reader once its subscription has a publisher matched,
the writer once its publisher has as many readers matched as the graph gave it (a reliable
writer sends only to the readers it has matched). Each then publishes its fully qualified
name, latched, on :data:`~activesurv_common.ros.topics.READY`, and the orchestrator releases
simulated time only when every such node has spoken (or after a timeout, with a warning). The
checks run on the steady clock: simulated time is held at 0 until then.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.timer import Timer
from std_msgs.msg import String

from activesurv_common.ros import qos, topics

PERIOD = 0.05
"""s between two looks at the subscriptions' matched publishers (steady clock)."""


def announce_when_matched(
    node: Node, inputs: Sequence[str] = (), outputs: Mapping[str, int] | None = None
) -> None:
    """Publish ``node``'s name on :data:`~activesurv_common.ros.topics.READY` (latched) once
    each of its subscriptions to ``inputs`` has a publisher matched and each of its publishers
    to a topic of ``outputs`` has at least that many subscriptions matched (topic names,
    resolved as the node resolves them; a topic the node has no endpoint on is not waited
    for)."""
    names = {node.resolve_topic_name(t) for t in inputs}
    wanted = {node.resolve_topic_name(t): n for t, n in (outputs or {}).items()}
    pub = node.create_publisher(String, topics.READY, qos.LATCHED)
    timer: Timer | None = None

    def look() -> None:
        subs = [s for s in node.subscriptions if s.topic_name in names]
        pubs = [p for p in node.publishers if p.topic_name in wanted]
        if any(s.get_publisher_count() < 1 for s in subs) or any(
            p.get_subscription_count() < wanted[p.topic_name] for p in pubs
        ):
            return
        if timer is not None:
            timer.cancel()
        pub.publish(String(data=node.get_fully_qualified_name()))

    timer = node.create_timer(PERIOD, look, clock=Clock(clock_type=ClockType.STEADY_TIME))
