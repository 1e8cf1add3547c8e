"""The ``xy_table`` node: moves the object along its preprogrammed path; optionally owns /clock.

Publishes:
    object_state (activesurv_interfaces/ObjectState): ground truth (top and side markers), for
        the simulated cameras and for evaluation; at ``publish_rate`` (simulated Hz).
    /clock (rosgraph_msgs/Clock) when ``publish_clock`` is true: simulated time starts at 0 and
        runs ``real_time_factor`` times as fast as the wall clock (slower when below 1).
Parameters: path_type (parabola, line, csv), path_points, csv_file, speed, acceleration,
    start_time (s of simulated time before the object starts), top_height, side_offset,
    side_normal, publish_rate, publish_clock, real_time_factor, frame_id.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any, cast

import rclpy
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_stages import qos, topics
from activesurv_stages.conversions import object_state_msg, sec_to_time
from activesurv_stages.errors import ConfigError, StageError
from activesurv_stages.xytable import ObjectModel, XYTable, named_path


class XYTableNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('xy_table', **kwargs)
        d = ParameterDescriptor
        self.declare_parameter('path_type', 'parabola', d(description='parabola, line or csv'))
        self.declare_parameter(
            'path_points',
            [0.17, 0.06, 0.25, 0.12, 0.33, 0.06],
            d(description='line: x0,y0,x1,y1; parabola: start,apex,end'),
        )
        self.declare_parameter('csv_file', '', d(description='t,x,y CSV for path_type csv'))
        self.declare_parameter('speed', 0.02, d(description='path speed (m/s)'))
        self.declare_parameter('acceleration', 0.02, d(description='path acceleration (m/s^2)'))
        self.declare_parameter('start_time', 1.0, d(description='s before the object starts'))
        self.declare_parameter('top_height', 0.08, d(description='top marker plane z (m)'))
        self.declare_parameter(
            'side_offset',
            [0.0, -0.03, -0.03],
            d(description='side marker centre minus top marker centre (m)'),
        )
        self.declare_parameter('side_normal', [0.0, -1.0, 0.0], d(description='side normal'))
        self.declare_parameter('publish_rate', 50.0, d(description='object_state rate (Hz)'))
        self.declare_parameter('publish_clock', True, d(description='own the simulated /clock'))
        self.declare_parameter('real_time_factor', 1.0, d(description='sim s per wall s'))
        self.declare_parameter('frame_id', 'world', d(description='frame of object_state'))
        self.declare_parameter(
            'wait_for_subscribers',
            0,
            d(description='hold simulated time at 0 until object_state has this many subscribers'),
        )
        self.declare_parameter('wait_timeout', 30.0, d(description='s to wait for them at most'))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # Values given at start-up (YAML, --ros-args -p) pass the same checks as later changes.
        declared = cast('dict[str, Parameter]', self.get_parameters_by_prefix(''))
        startup = self._on_set_parameters([p for p in declared.values() if p.value is not None])
        if not startup.successful:
            raise ValueError(f'invalid parameter: {startup.reason}')

        g = self.get_parameter
        path = named_path(
            str(g('path_type').value),
            list(g('path_points').value),
            float(g('speed').value),
            float(g('acceleration').value),
            str(g('csv_file').value),
        )
        off = [float(v) for v in g('side_offset').value]
        nrm = [float(v) for v in g('side_normal').value]
        if len(off) != 3 or len(nrm) != 3:
            raise ConfigError('side_offset and side_normal need 3 numbers each')
        model = ObjectModel(
            float(g('top_height').value), (off[0], off[1], off[2]), (nrm[0], nrm[1], nrm[2])
        )
        self.table = XYTable(path, float(g('start_time').value), model)
        self.publish_clock = bool(g('publish_clock').value)
        self.rtf = float(g('real_time_factor').value)
        self.frame_id = str(g('frame_id').value)
        self._wall0: float | None = None  # simulated time starts when everyone listens
        self._created = time.monotonic()
        self._wait_for = int(g('wait_for_subscribers').value)
        self._wait_timeout = float(g('wait_timeout').value)
        self._clock_pub = (
            self.create_publisher(Clock, topics.CLOCK, qos.CLOCK) if self.publish_clock else None
        )
        self._pub = self.create_publisher(ObjectStateMsg, topics.OBJECT_STATE, qos.STATE)
        rate = float(g('publish_rate').value)
        # With its own clock the node steps on the wall clock; otherwise on its node clock.
        self.create_timer(
            1.0 / (rate * self.rtf) if self.publish_clock else 1.0 / rate, self._on_tick
        )
        self.get_logger().info(
            f'path of {self.table.path.duration:.1f} s from t={self.table.start_time:.1f} s'
            + (f', owning /clock at {self.rtf:g}x real time' if self.publish_clock else '')
        )

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name in ('publish_rate', 'real_time_factor', 'speed', 'acceleration') and (
                not isinstance(p.value, float) or not math.isfinite(p.value) or p.value <= 0.0
            ):
                return SetParametersResult(
                    successful=False, reason=f'{p.name} must be a finite float > 0'
                )
        return SetParametersResult(successful=True)

    def sim_time(self) -> float:
        if self.publish_clock:
            if self._wall0 is None:
                return 0.0
            return (time.monotonic() - self._wall0) * self.rtf
        return self.get_clock().now().nanoseconds * 1e-9

    def _ready(self) -> bool:
        if self._wall0 is not None:
            return True
        listeners = self._pub.get_subscription_count()
        waited = time.monotonic() - self._created
        if listeners >= self._wait_for or waited > self._wait_timeout:
            if listeners < self._wait_for:
                self.get_logger().warning(
                    f'starting with {listeners} of {self._wait_for} object_state subscribers '
                    f'after {waited:.0f} s'
                )
            self._wall0 = time.monotonic()
            self.get_logger().info('simulated time starts')
            return True
        return False

    def _on_tick(self) -> None:
        if self.publish_clock and not self._ready():
            if self._clock_pub is not None:
                self._clock_pub.publish(Clock(clock=sec_to_time(0.0)))
            return
        t = self.sim_time()
        stamp = sec_to_time(t)
        if self._clock_pub is not None:
            self._clock_pub.publish(Clock(clock=stamp))
        self._pub.publish(object_state_msg(self.table.state(t), stamp, self.frame_id))


# A bad parameter or configuration file: one line on stderr and exit status 1, no traceback.
STARTUP_ERRORS = (ValueError, OSError, ParameterException, StageError)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    try:
        node = XYTableNode()
    except STARTUP_ERRORS as exc:
        print(f'xy_table: error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
