"""The ``table_runner`` node: a real xy table runs the experiment's path; its reports are truth.

With ``run_path`` it streams the path (parabola, line or csv, as the simulated ``xy_table``
takes it) to the table's ``stage_bridge`` as short straight moves (``xy_table/stage/goal``,
both joints in one goal: one straight move on the controller), timed from ``time_origin`` (wall
clock, s since the epoch) and ``start_time``. Always, each position the bridge reports
(``xy_table/stage/joint_states``) becomes an ``object_state`` with the poll's stamp: what the
evaluation takes as truth, as the paper measured it with the motion controller.

Parameters: see ``config/table_runner.yaml``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState

from activesurv_common.errors import GeometryError
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import joint_vector, sec_to_time, time_to_sec
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_hardware.errors import HardwareError
from activesurv_hardware.path_runner import PathRunner, StreamRunner, TruthFromController
from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_interfaces.msg import StageGoal
from activesurv_sim.ros.table_messages import object_state_msg
from activesurv_sim.stream import PATH_KINDS, ObjectStream
from activesurv_sim.xytable import named_path
from activesurv_stages.errors import StageError

TABLE = 'xy_table'
PARAMS = (
    Param('run_path', True, 'stream the path to the table (False: only publish the truth)'),
    Param(
        'path_type',
        'parabola',
        "object path; stream: a session's objects one after another",
        choices=('parabola', 'line', 'csv', 'stream'),
    ),
    Param('stream_seed', 1, "stream: seeds the objects' paths"),
    Param('arrival_interval', 30.0, 'stream: s from one entry to the next', above=0.0),
    Param('path_kinds', list(PATH_KINDS), 'stream: path kinds drawn'),
    Param('path_points', [0.13, 0.05, 0.25, 0.09, 0.37, 0.05], 'path points (m)'),
    Param('csv_file', '', 't,x,y CSV for path_type csv'),
    Param('speed', 0.02, 'path speed (m/s)', above=0.0),
    Param('acceleration', 0.02, 'path acceleration (m/s^2)', above=0.0),
    Param('start_time', 0.5, 's after time_origin the path starts', minimum=0.0),
    Param('time_origin', 0.0, 'wall clock (s since the epoch) of run time 0; 0: now + 5 s'),
    Param('segment', 0.1, 's of path per streamed move', above=0.0),
    Param('lead', 0.3, 's the streamed moves run ahead of the clock', above=0.0),
    Param('approach_speed', 0.05, 'm/s to the path start', above=0.0),
    Param('joints', ['table_x', 'table_y'], 'the table controller joints (x, y)'),
    Param('top_height', 0.08, 'top marker plane z (m)'),
    Param('side_offset', [0.0, -0.03, -0.03], 'side marker centre minus top marker centre (m)'),
    Param('side_normal', [0.0, -1.0, 0.0], 'side marker normal'),
    Param('frame_id', 'world', 'frame of the object state'),
)


class TableRunnerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('table_runner', **kwargs)
        declare(self, PARAMS)
        v = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.joints = [str(j) for j in v['joints']]
        if len(self.joints) != 2:
            raise HardwareError(f'joints: the table has two (x, y), got {self.joints}')
        try:
            model = ObjectGeometry(
                float(v['top_height']),
                tuple(float(x) for x in v['side_offset']),  # type: ignore[arg-type]
                tuple(float(x) for x in v['side_normal']),  # type: ignore[arg-type]
            )
        except GeometryError as exc:
            raise HardwareError(f'object: {exc}') from exc
        self.truth = TruthFromController(model)
        self.frame_id = str(v['frame_id'])
        origin = float(v['time_origin'])
        self.origin = origin if origin > 0.0 else time.time() + 5.0
        self.runner: PathRunner | StreamRunner | None = None
        if v['run_path'] and v['path_type'] == 'stream':
            stream = ObjectStream(
                int(v['stream_seed']),
                float(v['arrival_interval']),
                float(v['start_time']),
                [str(k) for k in v['path_kinds']],
                speed=float(v['speed']),
                acceleration=float(v['acceleration']),
                model=model,
            )
            self.runner = StreamRunner(
                stream, float(v['segment']), float(v['lead']), 2 * float(v['approach_speed'])
            )
        elif v['run_path']:
            path = named_path(
                str(v['path_type']),
                [float(x) for x in v['path_points']],
                float(v['speed']),
                float(v['acceleration']),
                str(v['csv_file']),
            )
            self.runner = PathRunner(
                path,
                float(v['start_time']),
                float(v['segment']),
                float(v['lead']),
                float(v['approach_speed']),
            )
        self.xy: np.ndarray | None = None
        self.moves = 0
        self._goal_pub = self.create_publisher(StageGoal, topics.goal(TABLE), qos.GOAL)
        self._state_pub = self.create_publisher(ObjectStateMsg, topics.OBJECT_STATE, qos.STATE)
        self.create_subscription(
            JointState, topics.joint_states(TABLE), self._on_joints, qos.SENSOR
        )
        if self.runner is not None:
            self.create_timer(float(v['segment']) / 2.0, self._on_tick)

    def _on_joints(self, msg: JointState) -> None:
        q = joint_vector(msg, self.joints)
        if q is None:
            return
        self.xy = np.asarray(q, dtype=np.float64)
        t = time_to_sec(msg.header.stamp)
        present = not isinstance(self.runner, StreamRunner) or self.runner.present(t - self.origin)
        state = self.truth.state(t, self.xy, present)
        self._state_pub.publish(object_state_msg(state, msg.header.stamp, self.frame_id))

    def _on_tick(self) -> None:
        assert self.runner is not None
        t = time.time() - self.origin
        move = self.runner.move(t)
        if move is None:
            return
        start = self.xy if self.xy is not None else np.array([move.x, move.y])
        d = np.abs(np.array([move.x, move.y]) - start)
        length = float(np.linalg.norm(d))
        share = d / length if length > 1e-9 else np.full(2, np.sqrt(0.5))
        goal = StageGoal()
        goal.header.stamp = self.get_clock().now().to_msg()
        goal.joint_names = list(self.joints)
        goal.positions = [move.x, move.y]
        goal.max_velocities = [max(float(s) * move.speed, 1e-5) for s in share]
        goal.arrival_time = sec_to_time(self.origin + t + 0.3)
        self._goal_pub.publish(goal)
        self.moves += 1


def main(args: list[str] | None = None) -> int:
    return run_node('table_runner', TableRunnerNode, args, errors=(HardwareError, StageError))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
