"""Every QoS profile of the graph, named by what it carries.

* Sensor streams are best effort (``qos_profile_sensor_data``), as real drivers publish them.
* Blackboard state (horizon, plan, stage goals) is reliable + transient-local, depth 1
  ("latched"): a node that joins late gets the current value.
* Per-demand events are reliable; on the blackboard they are transient-local with the last 50,
  so a restarted fusion node re-collects the requests and observations of recent demands.
"""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)


def _profile(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


# Camera streams, joint states, heartbeats: best effort, as real drivers publish.
SENSOR = qos_profile_sensor_data
# Triggered frames the imager must not miss: reliable (a best-effort subscriber still matches).
SENSOR_RELIABLE = _profile(5)
# Joint states and object states as published: reliable, so recorders get every sample;
# best-effort (SENSOR) subscribers match them too.
STATE = _profile(20)
# Blackboard state: the newest, kept for late joiners.
LATCHED = _profile(1, latched=True)
GOAL = LATCHED
ESTOP = LATCHED  # a bridge started after the e-stop was raised still sees it
# Per-demand events (capture requests, observations) as subscribed by the imagers.
EVENTS = _profile(50)
# Per-demand events on the blackboard (publishers keep the last 50 for late joiners).
EVENTS_LATCHED = _profile(50, latched=True)
# Results (estimates, fused poses): a late recorder or evaluator still gets the last ones.
RESULTS = _profile(20, latched=True)
# rclpy's time source subscribes to /clock best effort, depth 1; a reliable publisher matches.
CLOCK = _profile(1)
CLOCK_SUBSCRIBER = _profile(1, reliable=False)
DIAGNOSTICS = _profile(10)
# The frame tree, as tf2_ros publishes it: /tf reliable depth 100, /tf_static latched depth 1.
TF = _profile(100)
TF_STATIC = _profile(1, latched=True)
# Small status topics of the tools (recorder status).
STATUS = _profile(10)

# What each topic of the graph is published with (global names; ``*`` matches a camera id).
# DDS discovery does not carry a publisher's history depth (rclpy reports 0), so the recorder
# takes the depth from here to note it in a bag, and replay offers it again.
PUBLISHED: dict[str, QoSProfile] = {
    '/clock': CLOCK,
    '/sim/clock_origin': LATCHED,
    '/object_state': STATE,
    '/overhead/fix': STATE,
    '/overhead/track': SENSOR,
    '/demand_horizon': LATCHED,
    '/dispatch_plan': LATCHED,
    '/dispatch_markers': LATCHED,
    '/capture_request': EVENTS_LATCHED,
    '/marker_observations': EVENTS_LATCHED,
    '/target_estimate': RESULTS,
    '/target_pose': RESULTS,
    '/diagnostics': DIAGNOSTICS,
    '/tf': TF,
    '/tf_static': TF_STATIC,
    '/*/image_raw': SENSOR_RELIABLE,
    '/*/camera_info': SENSOR_RELIABLE,
    '/*/stage/joint_states': STATE,
    '/*/stage/goal': GOAL,
    '/*/imager/heartbeat': SENSOR,
    '/*/marker_annotations': EVENTS,
    '/*/preview/image_raw': SENSOR_RELIABLE,
    '/sim/planned_object_state': EVENTS,
    '/sim/*/planned_joint_states': EVENTS,
}


def published_depth(topic: str) -> int | None:
    """The history depth ``topic`` is published with in this graph, or None if not ours."""
    parts = topic.split('/')
    for pattern, profile in PUBLISHED.items():
        pat = pattern.split('/')
        if len(pat) == len(parts) and all(p in ('*', q) for p, q in zip(pat, parts, strict=True)):
            return int(profile.depth)
    return None
