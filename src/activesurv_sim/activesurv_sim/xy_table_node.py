"""The ``xy_table`` node: moves the object along its preprogrammed path; optionally owns /clock.

Publishes:
    object_state (activesurv_interfaces/ObjectState): ground truth (top and side markers), for
        the simulated cameras and for evaluation; at ``publish_rate`` (simulated Hz), with a
        ``publish_phase`` on the grid ``phase + n / rate`` (the timer runs twice as fast).
    sim/instant_object_state (ObjectState): with ``demand_states``, the states stamped within
        two periods before and one after each requested instant, for the cameras that image
        on requests only (:mod:`activesurv_sim.instant_window`).
    /clock (rosgraph_msgs/Clock) when ``publish_clock`` is true: simulated time starts at 0 and
        runs ``real_time_factor`` times as fast as the wall clock (slower when below 1).
Subscribes:
    capture_request (activesurv_interfaces/CaptureRequest): at each demand instant the table
        publishes the object's state stamped exactly then (the paper's motion controller
        records the target's exact pose at the demand instants), and, when it owns /clock, a
        clock tick at exactly that instant: every node's timers see the instant (a regular
        state and tick that close are skipped). With ``instant_ticks`` false the instant gets
        its state only, ``instant_state_delay`` (simulated s) later, past the cameras' imaging
        (no process wakes for a tick then, and a regular tick that close is kept).
        ``clock_period`` thins the regular ticks (not the states): at most one per that much
        simulated time. On the request it also publishes ``sim/planned_object_state`` (the
        simulated cameras render ahead with it): :mod:`activesurv_sim.ros.table_instants`.
With ``hold_until_released`` it holds time at 0 (as it does for the readers it waits for) until
the latched ``/sim/time_release`` (std_msgs/Empty) comes: the orchestrator starts it with the
graph and releases it once every node is up.
Parameters: see ``config/xy_table.yaml`` (path_type stream: ``activesurv_sim.stream``).
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Empty, Float64MultiArray

from activesurv_common.pacing import PhaseLock
from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import sec_to_time
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import declare
from activesurv_interfaces.msg import CaptureRequest
from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_sim.errors import SimError
from activesurv_sim.ros.table_instants import TableInstants
from activesurv_sim.ros.table_messages import object_state_msg, table_states
from activesurv_sim.stream import table_from_parameters
from activesurv_sim.xy_table_params import PARAMS
from activesurv_sim.xytable import XYTable, near_instant, start_shortfall
from activesurv_stages.errors import StageError


class XYTableNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('xy_table', **kwargs)
        declare(self, PARAMS)

        g = self.get_parameter
        self.table = table_from_parameters({p.name: g(p.name).value for p in PARAMS})
        self.publish_clock = bool(g('publish_clock').value)
        self.rtf = float(g('real_time_factor').value)
        self.frame_id = str(g('frame_id').value)
        self._wall0: float | None = None  # simulated time starts when everyone listens
        self._created = time.monotonic()
        wait = [int(g(f'wait_for_{n}subscribers').value) for n in ('', 'clock_', 'instant_')]
        names = ('object_state', '/clock', topics.INSTANT_OBJECT_STATE)  # said when one is short
        self._wait_for = dict(zip(names, wait, strict=True))
        self._wait_timeout = float(g('wait_timeout').value)
        # Started with the graph, time held until the orchestrator has every node up.
        self._held = bool(g('hold_until_released').value)
        if self._held:
            self.create_subscription(Empty, topics.TIME_RELEASE, self._on_release, qos.LATCHED)
        self._clock_pub = (
            self.create_publisher(Clock, topics.CLOCK, qos.CLOCK) if self.publish_clock else None
        )
        origin = topics.CLOCK_ORIGIN  # simulated = (steady - data[0]) * data[1]; data[2]: phase
        self._origin_pub = (
            self.create_publisher(Float64MultiArray, origin, qos.LATCHED)
            if self.publish_clock
            else None
        )
        self._pub = self.create_publisher(ObjectStateMsg, topics.OBJECT_STATE, qos.STATE)
        self._last_clock = -1.0
        planned = topics.PLANNED_OBJECT_STATE
        self._instant_ticks = bool(g('instant_ticks').value)
        self.instants = TableInstants(
            self,
            self.sim_time,
            (lambda: self._wall0) if self.publish_clock else None,
            self.rtf,
            lambda t: self._states(t, sec_to_time(t)),
            self.create_publisher(ObjectStateMsg, planned, qos.EVENTS),
            lambda t, states, tick: self._publish_at(t, states, tick),
            self._instant_ticks,
            float(g('instant_state_delay').value),
        )
        self._relay_pub: Publisher | None = None
        self._clock_period = float(g('clock_period').value)
        self._period = 1.0 / float(g('publish_rate').value)
        if bool(g('demand_states').value):
            cb = self.instants.on_request
            self.create_subscription(CaptureRequest, topics.CAPTURE_REQUEST, cb, qos.EVENTS)
            # Two states before an instant, its own and one after (the grid is half a period
            # off the instants'): the states a camera imaging on requests reads.
            relay = self.create_publisher(ObjectStateMsg, topics.INSTANT_OBJECT_STATE, qos.EVENTS)
            self.instants.relay_to(relay, 2.0 * self._period, self._period)
            self._relay_pub = relay
        phase = self._phase = float(g('publish_phase').value)
        self._grid = PhaseLock(1.0 / self._period, phase) if phase else None
        step = self._period / (2.0 if self._grid else 1.0)  # on a grid: a tick near each point
        # With its own clock the node steps on the wall clock; otherwise on its node clock.
        self.create_timer(step / self.rtf if self.publish_clock else step, self._on_tick)
        what = (
            f'path of {self.table.path.duration:.1f} s from t={self.table.start_time:.1f} s'
            if isinstance(self.table, XYTable)
            else f'a stream of objects, one every {self.table.arrival_interval:g} s or more'
        )
        clock = f', owning /clock at {self.rtf:g}x real time' if self.publish_clock else ''
        self.get_logger().info(what + clock)

    def sim_time(self) -> float:
        if self.publish_clock:
            if self._wall0 is None:
                return 0.0
            return (time.monotonic() - self._wall0) * self.rtf
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_release(self, msg: Empty) -> None:
        if self._held:
            self._held, self._created = False, time.monotonic()  # the timeout counts from now

    def _ready(self) -> bool:
        if self._wall0 is not None:
            return True
        if self._held:
            return False
        heard = {'object_state': self._pub.get_subscription_count()}
        if self._relay_pub is not None:
            heard[topics.INSTANT_OBJECT_STATE] = self._relay_pub.get_subscription_count()
        if self._clock_pub is not None:
            heard['/clock'] = self._clock_pub.get_subscription_count()
        short = start_shortfall(heard, self._wait_for)
        waited = time.monotonic() - self._created
        if not short or waited > self._wait_timeout:
            if short:
                self.get_logger().warning(f'starting with {short} subscribers ({waited:.0f} s)')
            self._wall0 = time.monotonic()
            if self._origin_pub is not None:
                origin = [self._wall0, self.rtf, self._phase]
                self._origin_pub.publish(Float64MultiArray(data=origin))
            self.get_logger().info('simulated time starts')
            return True
        return False

    def _on_tick(self) -> None:
        if self.publish_clock and not self._ready():
            if self._clock_pub is not None:
                self._clock_pub.publish(Clock(clock=sec_to_time(0.0)))
            return
        t = self.sim_time()
        if self._grid is not None and not self._grid.ready(t):
            return
        near = near_instant(t, self.instants.fired, self._period)
        if not near or not self._instant_ticks:
            tick = t >= self._last_clock + self._clock_period - 1e-6  # every timer wakes on it
            if not near:
                self.instants.flush()  # an instant's state still waiting goes first
            self._publish_at(t, states=not near, tick=tick)

    def _publish_at(self, t: float, states: bool = True, tick: bool = True) -> None:
        stamp = sec_to_time(t)  # states, then the tick that wakes all (docs/performance.md)
        msgs = self._states(t, stamp) if states else []
        for msg in msgs:
            self._pub.publish(msg)
        self.instants.published(t, msgs)
        if tick and self._clock_pub is not None and t > self._last_clock:
            self._clock_pub.publish(Clock(clock=stamp))  # simulated time never runs back
            self._last_clock = t

    def _states(self, t: float, stamp: Any) -> list[ObjectStateMsg]:
        """The object states at ``t``: one, or one per lane with several objects at once."""
        return [
            object_state_msg(st, stamp, self.frame_id, i, k)
            for i, k, st in table_states(self.table, t)
        ]

    def flush(self) -> None:
        self.instants.flush()  # at stop: the instant's state still waiting


def main(args: list[str] | None = None) -> int:
    flush = XYTableNode.flush
    return run_node('xy_table', XYTableNode, args, on_stop=flush, errors=(StageError, SimError))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown (a SIGTERM's 10 s)
