"""The ``lab_camera`` node: a simulated camera that behaves like a free-running camera driver.

For the hardware-in-the-loop lab (``activesurv lab``). It exposes on its own wall clock at
``frame_rate`` (its phase is not the demand instants'), each exposure of that grid even when
its timer fires late (:class:`~activesurv_common.pacing.ExposureClock`), renders the scene as
the stage and table controllers report it (``<camera_id>/stage/joint_states``,
``object_state``), and publishes best effort, as camera drivers do, each frame stamped on
arrival: the exposure instant plus ``exposure_delay`` (exposure and read-out) plus Gaussian
``jitter`` plus its clock's ``clock_offset``; ``drop_rate`` of the frames never arrive. Nothing
here knows a capture request. Optics and mount come from the rig file (the truth),
``camera_info`` from the calibration the lab's driver ships (``camera_info_file``). What the
carriage carries follows what the lab is used for: the object while something reports it (a
hardware run's ``table_runner`` publishes ``object_state``), else the commissioning boards at
the position the table controller reports (``xy_table/stage/joint_states``).
Parameters: ``sim_camera``'s but its clock's, and ``exposure_delay``, ``jitter``, ``drop_rate``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_srvs.srv import Trigger

from activesurv_common.errors import CommonError
from activesurv_common.pacing import ExposureClock
from activesurv_common.ros import diagnostics, qos, topics
from activesurv_common.ros.conversions import (
    MOUNT_PARAMETERS,
    CameraInfoStamper,
    declare_mount_parameters,
    gray_to_image,
    joint_vector,
    mount_from_parameters,
    object_state_vector,
    sec_to_time,
    time_to_sec,
)
from activesurv_common.ros.node import exit_now, run_node
from activesurv_common.ros.parameters import Param, declare
from activesurv_interfaces.msg import ObjectState
from activesurv_sim import conversions as conv
from activesurv_sim.conversions import published_model, simulated_camera
from activesurv_sim.errors import SimError
from activesurv_sim.lab_stats import LabCameraStats
from activesurv_sim.sim_camera import on_table
from activesurv_sim.sim_camera_params import PARAMS as SIM_CAMERA_PARAMS
from activesurv_sim.xytable import TABLE_ID, TABLE_JOINTS

LAB_PARAMS = (
    Param('exposure_delay', 0.02, 's from exposure to the frame stamp (read-out)', minimum=0.0),
    Param('jitter', 0.002, 'std of the stamp around it (s)', minimum=0.0),
    Param('clock_offset', 0.0, "s the camera's clock is ahead of the host's (in its stamps)"),
    Param('drop_rate', 0.01, 'fraction of frames that never arrive', minimum=0.0, maximum=1.0),
    Param('software_trigger', False, 'expose on ~/trigger (std_srvs/Trigger), not free-running'),
)
OWN_CLOCK = ('frame_phase', 'own_trigger', 'remote_delay')  # own clock; no imager beside it
NOT_LAB = (*OWN_CLOCK, 'instant_states')  # a lab camera free-runs on the table's reports
CAMERA_PARAMS = tuple(q for q in SIM_CAMERA_PARAMS if q.name not in NOT_LAB)
PARAMS = CAMERA_PARAMS + LAB_PARAMS
# Exposures a late timer still makes (a demand instant's burst of work on the host); a host
# that cannot render the rate at all sheds the older ones (``lost``), not every later frame.
LATE_PERIODS = 3.0


class LabCameraNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__('lab_camera', **kwargs)
        declare(self, PARAMS)
        declare_mount_parameters(self)
        v = {q.name: self.get_parameter(q.name).value for q in PARAMS}
        self.camera_id = str(v['camera_id'])
        mount = mount_from_parameters(
            self.camera_id, {n: self.get_parameter(n).value for n in MOUNT_PARAMETERS}
        )
        params = {q.name: v[q.name] for q in CAMERA_PARAMS}
        self.sim = simulated_camera({**params, 'payload': 'object'}, mount)
        self.boards = simulated_camera({**params, 'payload': 'board'}, mount)
        self.sim.warm_up()
        self.frame_id = f'{self.camera_id}_optical_frame'
        self.info = CameraInfoStamper(published_model(params, self.sim), self.frame_id)
        rate = float(v['frame_rate'])
        if not rate > 0.0:
            raise SimError('a lab camera free-runs: frame_rate must be > 0 Hz')
        self.delay, self.jitter = float(v['exposure_delay']), float(v['jitter'])
        self.clock_offset = float(v['clock_offset'])
        self.drop_rate, self.hold = float(v['drop_rate']), float(v['state_hold'])
        self.rng = np.random.default_rng(int(v['seed']))
        self.pending: list[float] = []
        self.stats = LabCameraStats(rate, time.monotonic())
        self._image_pub = self.create_publisher(Image, topics.image(self.camera_id), qos.SENSOR)
        self._info_pub = self.create_publisher(
            CameraInfo, topics.camera_info(self.camera_id), qos.SENSOR
        )
        self._diag_pub = self.create_publisher(
            diagnostics.DiagnosticArray, topics.DIAGNOSTICS, qos.DIAGNOSTICS
        )
        self.create_subscription(ObjectState, topics.OBJECT_STATE, self._on_object, qos.SENSOR)
        table = topics.joint_states(TABLE_ID)
        self.create_subscription(JointState, table, self._on_table, qos.SENSOR)
        if self.sim.joint_names:
            self.create_subscription(
                JointState, topics.joint_states(self.camera_id), self._on_joints, qos.SENSOR
            )
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.grid: ExposureClock | None = None  # a triggered driver: an exposure per call
        if v['software_trigger']:
            self.create_service(Trigger, '~/trigger', self._on_trigger)
        else:  # free-running: the exposures of its own grid, though its timer be late
            now = self.get_clock().now().nanoseconds * 1e-9
            self.grid = ExposureClock(rate, now, max_late=LATE_PERIODS / rate)
            self.create_timer(1.0 / rate, self._expose, clock=steady)
        self.create_timer(1.0, self._publish_diagnostics, clock=steady)
        self.create_timer(10.0, self._say_rate, clock=steady)
        self.get_logger().info(conv.DRIVER_UP)  # the lab reports ready when every camera has

    def _on_object(self, msg: ObjectState) -> None:
        self.sim.objects.add(time_to_sec(msg.header.stamp), object_state_vector(msg))
        self._develop()

    def _on_table(self, msg: JointState) -> None:
        xy = joint_vector(msg, TABLE_JOINTS)
        if xy is not None:
            self.boards.objects.add(time_to_sec(msg.header.stamp), np.r_[xy, [0.0] * 7])
            self._develop()

    def _on_joints(self, msg: JointState) -> None:
        q = joint_vector(msg, self.sim.joint_names)
        if q is not None:
            for sim in (self.sim, self.boards):
                sim.joints.add(time_to_sec(msg.header.stamp), q)
            self._develop()

    def _on_trigger(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        self._expose()
        return Trigger.Response(success=True)

    def _expose(self) -> None:
        """The exposures up to now; each frame is made once the controllers have reported
        past its exposure."""
        now = self.get_clock().now().nanoseconds * 1e-9
        due = [now] if self.grid is None else self.grid.due(now)
        self.stats.exposures += len(due)
        self.stats.lost = self.grid.lost if self.grid is not None else 0
        self.pending.extend(due)
        self._develop()

    def _develop(self) -> None:
        # What the camera saw at t is where the stages and the table were at t: render it when
        # reports stamped at or after t have come (they come at the controllers' poll rate).
        now = self.get_clock().now().nanoseconds * 1e-9
        while self.pending:
            t = self.pending[0]
            sim = on_table(self.sim, self.boards, t)
            seen = (sim.objects.latest_time or -1e18) >= t and (
                not sim.joint_names or (sim.joints.latest_time or -1e18) >= t
            )
            if not seen and now - t < self.hold:
                return
            self.pending.pop(0)
            self._shoot(sim, t)

    def _shoot(self, sim: Any, t: float) -> None:
        started = time.perf_counter()
        try:
            gray = sim.render_at(t, self.hold)
        except (SimError, CommonError):
            self.stats.missed += 1  # no state yet (controllers still connecting): nothing to see
            return
        self.stats.render_s += time.perf_counter() - started
        if self.rng.random() < self.drop_rate:
            self.stats.dropped += 1
            return
        noise = self.jitter * float(self.rng.standard_normal())
        stamp = sec_to_time(t + self.delay + self.clock_offset + noise)
        self._image_pub.publish(gray_to_image(gray, self.frame_id, stamp))
        self._info_pub.publish(self.info(stamp))
        self.stats.sent(t, self.get_clock().now().nanoseconds * 1e-9)

    def _say_rate(self) -> None:
        """What the camera achieves on this machine (a busy one delivers late)."""
        self.get_logger().info(self.stats.summary(time.monotonic()))

    def _publish_diagnostics(self) -> None:
        name, st = f'activesurv/lab_camera/{self.camera_id}', self.stats
        s = diagnostics.status(name, self.camera_id, st.short(), st.values(), diagnostics.OK)
        self._diag_pub.publish(diagnostics.array(self.get_clock().now().to_msg(), s))


def main(args: list[str] | None = None) -> int:
    return run_node('lab_camera', LabCameraNode, args, errors=(SimError, CommonError))


if __name__ == '__main__':
    exit_now(main())  # no interpreter teardown once main is done
