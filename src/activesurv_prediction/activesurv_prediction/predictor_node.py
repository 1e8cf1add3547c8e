"""The ``predictor`` node: overhead fixes in, the rolling horizon of demand points out.

Subscribes: overhead/fix (geometry_msgs/PointStamped, world; from ``overhead_locator``).
Publishes: demand_horizon (activesurv_interfaces/DemandHorizon, latched), overhead/track
    (geometry_msgs/PointStamped, each accepted fix), object_tracks
    (activesurv_interfaces/ObjectTracks: every track's filtered estimate at each fix),
    /diagnostics.
Parameters: see ``config/predictor.yaml``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace
from typing import Any

import numpy as np
from geometry_msgs.msg import PointStamped, PoseArray
from rclpy.node import Node
from rclpy.parameter import Parameter

from activesurv_common.ros import diagnostics, qos, topics
from activesurv_common.ros.conversions import time_to_sec
from activesurv_common.ros.node import run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_interfaces.msg import DemandHorizon, ObjectTracks
from activesurv_prediction.conversions import horizon_to_msg, tracks_to_msg
from activesurv_prediction.demands import TargetGeometry, demand_source, predict_demands
from activesurv_prediction.errors import PredictionError
from activesurv_prediction.multi import MultiTracker
from activesurv_prediction.predictor import make_predictor
from activesurv_prediction.tracker import Tracker, TrackState, Workspace, fix_statistics


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
)


DIAG = (topics.DIAGNOSTICS, qos.DIAGNOSTICS)


class PredictorNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('predictor', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter_or(p.name, Parameter(p.name)).value for p in PARAMS}
        v['demand_times'] = v['demand_times'] or []  # unset: the regular schedule
        self.schedule, self.objects = demand_source(
            str(v['demand_mode']),
            v['demand_times'],
            (float(v['first_demand']), float(v['service_interval']), int(v['demand_count'])),
            float(v['demand_interval']),
            v['demand_lines'],
            v['demand_region'],
            float(v['demand_freeze']),
        )
        self.geometry = TargetGeometry.create(v['side_marker_offset'], v['side_marker_normal'])
        self.tracker = Tracker(
            make_predictor(
                str(v['model']),
                measurement_std=float(v['measurement_std']),
                jerk_std=float(v['jerk_std']),
                gate=float(v['gate']),
            ),
            Workspace(*[float(x) for x in v['workspace']]),
            confirm_fixes=int(v['confirm_fixes']),
            lost_timeout=float(v['lost_timeout']),
        )
        self.marker_height = float(v['marker_height'])
        self.horizon = int(v['horizon'])
        self.frame_id = str(v['frame_id'])
        self._fix_times: deque[float] = deque(maxlen=60)
        self._innovations: deque[float] = deque(maxlen=300)
        self._fixes = 0
        self._bad_fixes = 0
        self._last_state = TrackState.NONE

        self._horizon_pub = self.create_publisher(
            DemandHorizon, topics.DEMAND_HORIZON, qos.LATCHED
        )
        self._track_pub = self.create_publisher(PointStamped, topics.OVERHEAD_TRACK, qos.SENSOR)
        self._tracks_pub = self.create_publisher(ObjectTracks, topics.OBJECT_TRACKS, qos.STATE)
        self._diag_pub = self.create_publisher(diagnostics.DiagnosticArray, *DIAG)
        self.multi: MultiTracker | None = None
        if int(v['objects_at_once']) > 1:
            if self.objects is None:
                raise PredictionError('several objects at once need demand_mode interval or lines')
            book = self.objects.book
            self.multi = MultiTracker(
                str(v['model']),
                float(v['measurement_std']),
                float(v['jerk_std']),
                int(v['confirm_fixes']),
                Workspace(*[float(x) for x in v['workspace']]),
                float(v['lost_timeout']),
                book.interval,
                book.lines,
                book.region,
                book.freeze,
                int(v['objects_at_once']),
            )
            self.create_subscription(PoseArray, topics.OVERHEAD_FIXES, self._on_fixes, qos.STATE)
        else:
            self.create_subscription(PointStamped, topics.OVERHEAD_FIX, self._on_fix, qos.STATE)
        self.create_timer(0.1, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)

    def _now(self) -> float:
        return float(self.get_clock().now().nanoseconds) * 1e-9

    def _on_fix(self, msg: PointStamped) -> None:
        self._fixes += 1
        t = time_to_sec(msg.header.stamp)
        xy = np.array([msg.point.x, msg.point.y], dtype=np.float64)
        if not np.all(np.isfinite(xy)):
            self._bad_fixes += 1
            return
        result = self.tracker.update(t, xy)
        if result is None:
            return
        if result.accepted:
            self._fix_times.append(t)
            self._track_pub.publish(msg)
        if math.isfinite(result.mahalanobis2):
            self._innovations.append(result.mahalanobis2)
        self._publish_horizon(t)

    def _on_fixes(self, msg: PoseArray) -> None:
        """Several objects: every top marker of one overhead frame."""
        assert self.multi is not None
        t = time_to_sec(msg.header.stamp)
        xy = [np.array([p.position.x, p.position.y], dtype=np.float64) for p in msg.poses]
        good = [v for v in xy if np.all(np.isfinite(v))]
        self._fixes += len(good)
        self._bad_fixes += len(xy) - len(good)
        self._fix_times.append(t)
        for text in self.multi.update(t, good):
            self.get_logger().info(text)
        self._publish_multi(t)

    def _publish_multi(self, now: float) -> None:
        assert self.multi is not None
        m = self.multi
        preds = m.horizon(now, self.horizon, self.geometry, self.marker_height)
        motion = replace(m.motion(), manoeuvre_count=m.manoeuvre_count())
        self._horizon_pub.publish(horizon_to_msg(preds, m.state(), now, self.frame_id, motion))
        self._tracks_pub.publish(
            tracks_to_msg(m.estimates(now), now, self.frame_id, self.marker_height)
        )

    def _publish_horizon(self, now: float) -> None:
        state = self.tracker.state
        preds: list[Any] = []
        if self.objects is not None:
            preds, events = self.objects.update(
                self.tracker, now, self.horizon, self.geometry, self.marker_height
            )
            for text in events:
                self.get_logger().info(text)
        elif state in (TrackState.TENTATIVE, TrackState.CONFIRMED):
            p, h = self.tracker.predictor, self.horizon
            preds = predict_demands(p, self.schedule, self.geometry, self.marker_height, now, h)
        self._horizon_pub.publish(
            horizon_to_msg(preds, state, now, self.frame_id, self.tracker.motion())
        )
        # A session numbers its objects at confirmation; an experiment has its tracks.
        object_id = (
            self.objects.book.object_id
            if self.objects is not None
            else self.tracker.tracks_started
        )
        self._tracks_pub.publish(
            tracks_to_msg(
                self.tracker.estimates(now, object_id), now, self.frame_id, self.marker_height
            )
        )
        if self.tracker.manoeuvre:
            self.get_logger().info(f'manoeuvre: the object is {self.tracker.manoeuvres.regime}')
        if state is not self._last_state:
            self.get_logger().info(f'track {self._last_state.name} -> {state.name}')
            self._last_state = state

    def _on_tick(self) -> None:
        if self.multi is not None:
            events = self.multi.check_timeout(self._now())
            for text in events:
                self.get_logger().info(text)
            if events:
                self._publish_multi(self._now())
            return
        if self.tracker.check_timeout(self._now()):
            self.get_logger().warning('track lost: object not seen for too long')
            self._publish_horizon(self._now())

    def _publish_diagnostics(self) -> None:
        state = self.tracker.state
        values = fix_statistics(list(self._fix_times), list(self._innovations))
        values.update(
            track_state=state.name,
            fixes=self._fixes,
            bad_fixes=self._bad_fixes,
            outliers_rejected=self.tracker.predictor.rejections,
            tracks_started=self.tracker.tracks_started,
            motion=self.tracker.manoeuvres.regime or '-',
            manoeuvres=self.tracker.manoeuvres.count,
        )
        if self.multi is not None:
            state = self.multi.state()
            values.update(
                track_state=state.name,
                tracks=len(self.multi.tracks),
                confirmed=sum(1 for k in self.multi.tracks if k.confirmed),
                objects_seen=self.multi.objects,
                manoeuvres=self.multi.manoeuvre_count(),
            )
        level = diagnostics.OK if state is TrackState.CONFIRMED else diagnostics.WARN
        s = diagnostics.status(
            'activesurv/predictor', 'predictor', f'track {state.name}', values, level
        )
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))


def main(args: list[str] | None = None) -> int:
    return run_node('predictor', PredictorNode, args, errors=(PredictionError,))


if __name__ == '__main__':
    raise SystemExit(main())
