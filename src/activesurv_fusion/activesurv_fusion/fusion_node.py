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
its predecessor left open. With the ``journal`` parameter (a file; the graph runs set it) the
answered demand indices survive the crash, so no demand is answered twice.
"""

from __future__ import annotations

import math
import os
import signal
import sys
from collections import Counter
from types import FrameType
from typing import Any, cast

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import ParameterException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from activesurv_fusion import qos, topics
from activesurv_fusion.collector import DemandCollector, DemandResult, DemandStatus, resolve
from activesurv_fusion.conversions import (
    observation_to_answer,
    request_fields,
    result_to_estimate,
    result_to_pose,
    time_to_sec,
)
from activesurv_fusion.errors import FusionError
from activesurv_interfaces.msg import CaptureRequest, MarkerObservation, TargetEstimate


def read_journal(path: str) -> set[int]:
    """Indices in the journal; a torn last line (a kill mid-write) is ignored."""
    try:
        with open(path, encoding='utf-8') as f:
            return {int(line) for line in f.read().split('\n') if line.strip().isdigit()}
    except FileNotFoundError:
        return set()


def append_journal(path: str, index: int) -> None:
    with open(path, 'a', encoding='utf-8') as f:
        f.write(f'{index}\n')
        f.flush()
        os.fsync(f.fileno())


class FusionNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('fusion', **kwargs)
        self.declare_parameter(
            'collect_timeout',
            2.0,
            ParameterDescriptor(
                description='seconds after a demand instant to wait for missing cameras',
                floating_point_range=[FloatingPointRange(from_value=0.01, to_value=600.0)],
            ),
        )
        self.declare_parameter(
            'z_sigma',
            3.0,
            ParameterDescriptor(
                description='abstract-sensor half-width in standard deviations (3: 99.74 %)',
                floating_point_range=[FloatingPointRange(from_value=0.1, to_value=10.0)],
            ),
        )
        self.declare_parameter(
            'max_faulty',
            -1,
            ParameterDescriptor(
                description='faulty cameras tolerated (k_f); -1: the largest k_f < k/2',
                integer_range=[IntegerRange(from_value=-1, to_value=64, step=1)],
            ),
        )
        self.declare_parameter(
            'frame_id', 'world', ParameterDescriptor(description='frame of the published poses')
        )
        self.declare_parameter(
            'journal',
            '',
            ParameterDescriptor(
                description='file of answered demand indices (kept across restarts); empty: none',
                read_only=True,
            ),
        )
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')
        self._collector = DemandCollector(float(self.get_parameter('collect_timeout').value))
        self._journal = str(self.get_parameter('journal').value)
        if self._journal:
            done = read_journal(self._journal)
            self._collector.mark_answered(done)
            if done:
                self.get_logger().info(
                    f'restarted: {len(done)} demands were answered before, up to {max(done)}'
                )

        self._estimate_pub = self.create_publisher(
            TargetEstimate, topics.TARGET_ESTIMATE, qos.RESULTS
        )
        self._pose_pub = self.create_publisher(
            PoseWithCovarianceStamped, topics.TARGET_POSE, qos.RESULTS
        )
        self._diag_pub = self.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS_LATCHED
        )
        self.create_subscription(
            MarkerObservation,
            topics.MARKER_OBSERVATIONS,
            self._on_observation,
            qos.EVENTS_LATCHED,
        )
        self.create_timer(0.05, self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)
        self._status_counts: Counter[str] = Counter()
        self._rejected = 0

    # -- parameters -------------------------------------------------------------------------
    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name in ('collect_timeout', 'z_sigma'):
                value = p.value
                if not isinstance(value, float) or not math.isfinite(value) or value <= 0.0:
                    return SetParametersResult(
                        successful=False, reason=f'{p.name} must be a finite float > 0'
                    )
            if p.name == 'frame_id' and not str(p.value):
                return SetParametersResult(successful=False, reason='frame_id must not be empty')
        for p in params:
            if p.name == 'collect_timeout' and hasattr(self, '_collector'):
                self._collector.set_timeout(float(p.value))
        return SetParametersResult(successful=True)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _max_faulty(self) -> int | None:
        value = int(self.get_parameter('max_faulty').value)
        return None if value < 0 else value

    # -- callbacks: convert, call the core, publish -----------------------------------------
    def _on_request(self, msg: CaptureRequest) -> None:
        index, demand_time, cameras, prior = request_fields(msg)
        if not math.isfinite(demand_time):
            self._rejected += 1
            self.get_logger().warning(f'ignored capture request {index}: bad demand instant')
            return
        if not self._collector.request(index, demand_time, cameras, self._now(), prior):
            self.get_logger().warning(f'capture request for demand {index} after it was answered')

    def _on_observation(self, msg: MarkerObservation) -> None:
        answer = observation_to_answer(msg)
        stamp = time_to_sec(msg.header.stamp)
        if not self._collector.observe(int(msg.demand_index), answer, self._now(), stamp):
            self.get_logger().warning(
                f'late observation from {msg.camera_id} for demand {msg.demand_index} dropped'
            )
        self._publish_ready(self._collector.pop_ready(self._now()))

    def _on_tick(self) -> None:
        self._publish_ready(self._collector.pop_ready(self._now()))

    def flush(self) -> None:
        """Answer every open demand now (on shutdown), so none is left silent."""
        self._publish_ready(self._collector.flush())

    def _publish_ready(self, batches: list[Any]) -> None:
        frame = str(self.get_parameter('frame_id').value)
        z = float(self.get_parameter('z_sigma').value)
        for batch in batches:
            result: DemandResult = resolve(batch, z=z, max_faulty=self._max_faulty())
            self._status_counts[result.status.name] += 1
            self._estimate_pub.publish(result_to_estimate(result, frame))
            if self._journal:
                append_journal(self._journal, result.index)
            pose = result_to_pose(result, frame)
            if pose is not None:
                self._pose_pub.publish(pose)
            log = self.get_logger()
            if result.status in (DemandStatus.OK, DemandStatus.PARTIAL):
                log.info(f'demand {result.index}: {result.status.name} {result.reason}'.strip())
            else:
                log.warning(f'demand {result.index}: {result.status.name}: {result.reason}')

    def _publish_diagnostics(self) -> None:
        status = DiagnosticStatus(name='activesurv/fusion', hardware_id='fusion')
        failures = self._status_counts['NO_OBSERVATIONS'] + self._status_counts['NO_CONSENSUS']
        status.level = DiagnosticStatus.WARN if failures else DiagnosticStatus.OK
        status.message = f'{sum(self._status_counts.values())} demands answered'
        status.values = [KeyValue(key=k, value=str(v)) for k, v in self._status_counts.items()]
        status.values += [
            KeyValue(key='open_demands', value=str(list(self._collector.open_indices))),
            KeyValue(key='late_observations', value=str(self._collector.late_observations)),
            KeyValue(key='rejected_requests', value=str(self._rejected)),
        ]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, FusionError)


def main(args: list[str] | None = None) -> int:
    # Own signal handling: on SIGINT/SIGTERM answer the open demands before the context goes.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = FusionNode()
    except STARTUP_ERRORS as exc:
        print(f'fusion: error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stopping = False

    def _stop(signum: int, frame: FrameType | None) -> None:
        nonlocal stopping
        stopping = True

    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    try:
        while rclpy.ok() and not stopping:
            executor.spin_once(timeout_sec=0.1)
        node.flush()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
