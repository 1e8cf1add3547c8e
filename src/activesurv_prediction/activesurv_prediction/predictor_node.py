"""The ``predictor`` node: overhead fixes in, the rolling horizon of demand points out.

Subscribes: overhead/fix (geometry_msgs/PointStamped, world; from ``overhead_locator``).
Publishes: demand_horizon (activesurv_interfaces/DemandHorizon, latched), overhead/track
    (geometry_msgs/PointStamped, each accepted fix), object_tracks
    (activesurv_interfaces/ObjectTracks: every track's filtered estimate at each fix),
    object_track_markers (visualization_msgs/MarkerArray, latched: the tracks for viewers),
    /diagnostics, activesurv/ready (std_msgs/String, latched: its name once overhead/fix has a
    publisher matched; a simulated run starts its time after it).
Parameters: see ``config/predictor.yaml``.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from geometry_msgs.msg import PointStamped, PoseArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from visualization_msgs.msg import MarkerArray

from activesurv_common.pacing import ViewThrottle
from activesurv_common.ros import diagnostics, local_topics, qos, ready, topics
from activesurv_common.ros.conversions import time_to_sec
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_interfaces.msg import DemandHorizon, ObjectTracks
from activesurv_prediction.conversions import horizon_to_msg, track_markers, tracks_to_msg
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.session import (
    HorizonUpdate,
    PredictionSession,
    PredictorConfig,
    finite_fix,
)
from activesurv_prediction.tracker import TrackState, Workspace, fix_statistics


def _workspace_problem(v: Any) -> str | None:
    try:
        Workspace(*[float(x) for x in v])
    except (PredictionError, TypeError) as exc:
        return f'workspace: {exc}'
    return None


PARAMS = (
    Param('marker_height', 0.08, 'top marker plane z (m)'),
    Param('first_demand', 4.0, 'first demand instant (s)'),
    Param('service_interval', 2.0, 'between demands (s)', above=0.0),
    Param('demand_count', 10, 'number of demand instants', minimum=1),
    Param('demand_times', Parameter.Type.DOUBLE_ARRAY, 'explicit instants (s); unset: above'),
    Param(
        'demand_mode',
        'schedule',
        'schedule: the fixed instants above; interval or lines: per object (continuous)',
        choices=('schedule', 'interval', 'lines'),
    ),
    Param('demand_interval', 2.0, "interval mode: s between an object's demands", above=0.0),
    Param('demand_phase', 0.0, 'interval mode: s after the entry grid', minimum=0.0),
    Param('demand_lines', [0.25], 'lines mode: x (m) of the lines whose crossings are demands'),
    Param(
        'demand_region',
        [0.0, 0.5, 0.0, 0.2],
        'continuous: where demand points may fall (x_min, x_max, y_min, y_max)',
        check=_workspace_problem,
    ),
    Param('demand_freeze', 1.0, 'lines mode: s before a crossing when it stops moving', above=0.0),
    Param('horizon', 5, 'demands on the rolling horizon (m)', minimum=1),
    Param('measurement_std', 0.5e-3, 'overhead fix std (m)', above=0.0),
    Param('model', 'imm', 'imm (manoeuvre-aware) or ca (round-1 filter)', choices=('imm', 'ca')),
    Param('jerk_std', 2e-4, 'ca model: process noise (m/s^3)', above=0.0),
    Param('gate', 50.0, 'chi-square outlier gate (2 dof)', above=0.0),
    Param('confirm_fixes', 10, 'fixes to confirm a track', minimum=1),
    Param('lost_timeout', 1.0, 'unseen s before track loss', above=0.0),
    Param(
        'workspace',
        [0.0, 0.5, 0.0, 0.2],
        'x_min, x_max, y_min, y_max (m)',
        check=_workspace_problem,
    ),
    Param('side_marker_offset', [0.0, -0.03, -0.03], 'side minus top marker centre (m)'),
    Param('side_marker_normal', [0.0, -1.0, 0.0], 'side marker normal (world)'),
    Param('frame_id', 'world', 'frame of the horizon'),
    Param(
        'objects_at_once',
        1,
        'continuous: objects expected at once; > 1 tracks every marker of overhead/fixes',
        minimum=1,
    ),
    Param('marker_period', 0.2, 's between markers (new tracks at once); 0: all', minimum=0.0),
)


DIAG = (topics.DIAGNOSTICS, qos.DIAGNOSTICS)


class PredictorNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('predictor', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter_or(p.name, Parameter(p.name)).value for p in PARAMS}
        config = PredictorConfig.from_parameters(v)
        self.session = PredictionSession(config)
        self.frame_id = str(v['frame_id'])
        self._fix_times: deque[float] = deque(maxlen=60)
        self._innovations: deque[float] = deque(maxlen=300)
        self._fixes = self._bad_fixes = 0
        self._markers = ViewThrottle(float(v['marker_period']))

        # In process first to the dispatcher and the frames node of its container.
        pub, track = local_topics.publisher, topics.OVERHEAD_TRACK
        self._horizon_pub = pub(self, DemandHorizon, topics.DEMAND_HORIZON, qos.LATCHED)
        self._track_pub = pub(self, PointStamped, track, qos.SENSOR)
        self._tracks_pub = self.create_publisher(ObjectTracks, topics.OBJECT_TRACKS, qos.STATE)
        self._markers_pub = self.create_publisher(
            MarkerArray, topics.OBJECT_TRACK_MARKERS, qos.LATCHED
        )
        self._diag_pub = self.create_publisher(diagnostics.DiagnosticArray, *DIAG)
        if self.session.multi is not None:
            self.create_subscription(PoseArray, topics.OVERHEAD_FIXES, self._on_fixes, qos.STATE)
        else:
            self.create_subscription(PointStamped, topics.OVERHEAD_FIX, self._on_fix, qos.STATE)
        ready.announce_when_matched(self, (topics.OVERHEAD_FIX, topics.OVERHEAD_FIXES))
        self.create_timer(0.1, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)

    def _now(self) -> float:
        return float(self.get_clock().now().nanoseconds) * 1e-9

    def _on_fix(self, msg: PointStamped) -> None:
        self._fixes += 1
        t = time_to_sec(msg.header.stamp)
        xy = finite_fix([msg.point.x, msg.point.y])
        if xy is None:
            self._bad_fixes += 1
            return
        out = self.session.on_fix(t, xy)
        if out is None:
            return
        if out.accepted:
            self._fix_times.append(t)
            self._track_pub.publish(msg)
        if math.isfinite(out.mahalanobis2):
            self._innovations.append(out.mahalanobis2)
        self._publish(out)

    def _on_fixes(self, msg: PoseArray) -> None:
        """Several objects: every top marker of one overhead frame."""
        t = time_to_sec(msg.header.stamp)
        xy = [finite_fix([p.position.x, p.position.y]) for p in msg.poses]
        good = [v for v in xy if v is not None]
        self._fixes += len(good)
        self._bad_fixes += len(xy) - len(good)
        self._fix_times.append(t)
        self._publish(self.session.on_fixes(t, good))

    def _on_tick(self) -> None:
        out = self.session.tick(self._now())
        if out is not None:
            self._publish(out)

    def _publish(self, out: HorizonUpdate) -> None:
        c = self.session.config
        self._horizon_pub.publish(
            horizon_to_msg(out.demands, out.state, out.stamp, self.frame_id, out.motion)
        )
        self._tracks_pub.publish(
            tracks_to_msg(out.tracks, out.stamp, self.frame_id, c.marker_height)
        )
        if self._markers.due(out.stamp, [(k.object_id, k.confirmed) for k in out.tracks]):
            markers = track_markers(out.tracks, out.stamp, self.frame_id, c.marker_height)
            self._markers_pub.publish(markers)
        log = self.get_logger()
        for text in out.events:
            # rclpy ties a severity to each call site: one call per severity.
            if text.startswith('track lost'):
                log.warning(text)
            else:
                log.info(text)

    def _publish_diagnostics(self) -> None:
        values = fix_statistics(list(self._fix_times), list(self._innovations))
        values.update(self.session.status(), fixes=self._fixes, bad_fixes=self._bad_fixes)
        state = self.session.state()
        level = diagnostics.OK if state is TrackState.CONFIRMED else diagnostics.WARN
        s = diagnostics.status(
            'activesurv/predictor', 'predictor', f'track {state.name}', values, level
        )
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))


def main(args: list[str] | None = None) -> int:
    return run_node('predictor', PredictorNode, args, errors=(PredictionError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
