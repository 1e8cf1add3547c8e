"""The ``fusion`` node: collect each demand's marker observations, fuse them, publish the result.

Subscribes:
    capture_request (activesurv_interfaces/CaptureRequest): which cameras serve which demand.
    marker_observations (activesurv_interfaces/MarkerObservation): per-camera estimates.
Publishes:
    target_estimate (activesurv_interfaces/TargetEstimate): one per demand, always (estimate or
        an explicit failure status).
    target_pose (geometry_msgs/PoseWithCovarianceStamped): the fused pose when there is one.
    /diagnostics (diagnostic_msgs/DiagnosticArray).
Parameters: see ``config/fusion.yaml``.

Requests and observations are subscribed transient-local (their publishers keep the last 50):
a fusion node restarted after a crash receives those of the recent demands and answers the ones
its predecessor left open. A demand is answered when every camera asked has, or at its deadline
(``collect_timeout`` past the instant), kept between ``/clock`` ticks on the clock owner's
mapping. With the ``journal`` parameter (a file; the graph runs set it) the
answered demand indices survive the crash, so no demand is answered twice. On SIGINT/SIGTERM
it answers every open demand before it stops.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from functools import partial
from typing import Any

from geometry_msgs.msg import PoseWithCovarianceStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from activesurv_common.ros import diagnostics, qos, ready, topics
from activesurv_common.ros.conversions import time_to_sec
from activesurv_common.ros.fine_clock import FineClock
from activesurv_common.ros.instants import InstantTimers
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import declare
from activesurv_fusion.collector import DemandBatch, DemandCollector, resolve
from activesurv_fusion.conversions import (
    observation_to_answer,
    request_fields,
    result_to_estimate,
    result_to_pose,
)
from activesurv_fusion.errors import FusionError
from activesurv_fusion.fusion_params import PARAMS
from activesurv_fusion.journal import append_journal, read_journal
from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, TargetEstimate


class FusionNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('fusion', **kwargs)
        declare(self, PARAMS)
        self._collector = DemandCollector(float(self.get_parameter('collect_timeout').value))
        self.add_on_set_parameters_callback(self._apply)
        self._journal = str(self.get_parameter('journal').value)
        if self._journal:
            done = read_journal(self._journal)
            self._collector.mark_answered(done)
            if done:
                self.get_logger().info(
                    f'restarted: {len(done)} demands were answered before, up to {max(done)}'
                )
        self._status_counts: Counter[str] = Counter()
        self._counts: Counter[str] = Counter()
        self._fine = FineClock(self.get_clock(), self)  # when an estimate is published: budget
        self._estimate_pub = self.create_publisher(
            TargetEstimate, topics.TARGET_ESTIMATE, qos.RESULTS
        )
        self._pose_pub = self.create_publisher(
            PoseWithCovarianceStamped, topics.TARGET_POSE, qos.RESULTS
        )
        self._diag_pub = self.create_publisher(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS_LATCHED
        )
        observations = topics.MARKER_OBSERVATIONS
        obs_qos = qos.EVENTS_LATCHED
        self.create_subscription(MarkerObservation, observations, self._on_observation, obs_qos)
        # A demand a camera never answers is decided at its deadline: on the clock owner's
        # mapping (between /clock ticks), else at the next tick of this timer.
        self._deadlines = InstantTimers(self)
        self.create_timer(0.05, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)
        if bool(self.get_parameter('announce_ready').value):  # simulated time waits for it
            inputs = (topics.CLOCK_ORIGIN, topics.CAPTURE_REQUEST, observations)
            ready.announce_when_matched(self, inputs)

    def _apply(self, params: list[Parameter]) -> SetParametersResult:
        """A changed collect_timeout applies to the open demands too (checked already)."""
        for p in params:
            if p.name == 'collect_timeout':
                self._collector.set_timeout(float(p.value))
        return SetParametersResult(successful=True)

    def _now(self) -> float:  # between /clock ticks too
        return self._fine.now()

    def _arm(self) -> None:
        for t in self._collector.deadlines():  # a timer per deadline (none without a mapping)
            self._deadlines.at(t, partial(self._on_deadline, t), exact=False)

    def _on_deadline(self, t: float) -> None:  # the timer's own instant: never a hair before it
        self._publish_ready(self._collector.pop_ready(max(self._now(), t)))

    # -- callbacks: convert, call the core, publish -----------------------------------------
    def _on_request(self, msg: CaptureRequest) -> None:
        index, demand_time, cameras, prior = request_fields(msg)
        if not math.isfinite(demand_time):
            self._counts['rejected_requests'] += 1
            return
        if not self._collector.request(index, demand_time, cameras, self._now(), prior):
            self._counts['requests_after_answer'] += 1
        self._arm()

    def _on_observation(self, msg: MarkerObservation) -> None:
        started = time.thread_time()  # fusion's compute on the budget: CPU, not waiting
        answer = observation_to_answer(msg)
        stamp = time_to_sec(msg.header.stamp)
        self._collector.observe(int(msg.demand_index), answer, self._now(), stamp)
        self._publish_ready(self._collector.pop_ready(self._now()), started)
        self._arm()

    def _on_tick(self) -> None:
        self._publish_ready(self._collector.pop_ready(self._now()))

    def flush(self) -> int:
        """Answer every open demand now (on shutdown), so none is left silent; returns how
        many were answered."""
        batches = self._collector.flush()
        self._publish_ready(batches)
        return len(batches)

    def _publish_ready(self, batches: list[DemandBatch], started: float | None = None) -> None:
        started = time.thread_time() if started is None else started
        frame = str(self.get_parameter('frame_id').value)
        z = float(self.get_parameter('z_sigma').value)
        max_faulty = int(self.get_parameter('max_faulty').value)
        for batch in batches:
            result = resolve(batch, z=z, max_faulty=None if max_faulty < 0 else max_faulty)
            self._status_counts[result.status.name] += 1
            estimate = result_to_estimate(result, frame, self._fine.now())
            estimate.compute_time = time.thread_time() - started
            self._estimate_pub.publish(estimate)
            started = time.thread_time()
            if self._journal:
                append_journal(self._journal, result.index)
            pose = result_to_pose(result, frame)
            if pose is not None:
                self._pose_pub.publish(pose)
            log = self.get_logger()
            if result.status.estimated:
                log.info(f'demand {result.index}: {result.status.name} {result.reason}'.strip())
            else:
                log.warning(f'demand {result.index}: {result.status.name}: {result.reason}')

    def _publish_diagnostics(self) -> None:
        failures = self._status_counts['NO_OBSERVATIONS'] + self._status_counts['NO_CONSENSUS']
        values: dict[str, Any] = {**self._status_counts, **self._counts}
        values.update(
            open_demands=list(self._collector.open_indices),
            late_observations=self._collector.late_observations,
            rejected_requests=self._counts['rejected_requests'],
        )
        s = diagnostics.status(
            'activesurv/fusion',
            'fusion',
            f'{sum(self._status_counts.values())} demands answered',
            values,
            diagnostics.WARN if failures else diagnostics.OK,
        )
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))


def main(args: list[str] | None = None) -> int:
    return run_node('fusion', FusionNode, args, on_stop=FusionNode.flush, errors=(FusionError,))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
