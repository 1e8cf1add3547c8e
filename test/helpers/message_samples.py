"""Deterministic sample values for every custom message type, shared by publisher and checker.

Run as a script it publishes each sample (repeatedly, until killed) on ``sample/<Type>``.
"""

from __future__ import annotations

import sys
import time
from typing import Any

MESSAGE_TYPES = (
    'Ellipse',
    'DemandPoint',
    'DemandHorizon',
    'SensorAssignment',
    'DispatchPlan',
    'CaptureRequest',
    'MarkerObservation',
    'TargetEstimate',
    'StageGoal',
    'ObjectState',
)


def sample(name: str) -> Any:
    """A message of type ``name`` with distinctive field values."""
    import activesurv_interfaces.msg as m

    if name == 'Ellipse':
        return m.Ellipse(
            center_x=320.5, center_y=240.25, semi_major=110.0, semi_minor=80.0, angle=0.5
        )
    if name == 'DemandPoint':
        d = m.DemandPoint(index=3)
        d.demand_instant.sec = 12
        d.pose.pose.position.x = 0.25
        d.pose.covariance[0] = 1e-6
        d.normal.y = -1.0
        return d
    if name == 'DemandHorizon':
        h = m.DemandHorizon(track_state=m.DemandHorizon.TRACK_CONFIRMED)
        h.header.frame_id = 'world'
        h.demands = [sample('DemandPoint'), sample('DemandPoint')]
        h.demands[1].index = 4
        return h
    if name == 'SensorAssignment':
        return m.SensorAssignment(
            camera_id='cam4',
            role=m.SensorAssignment.ROLE_PREASSIGNED,
            demand_index=4,
            joint_names=['cam4_x', 'cam4_yaw'],
            desired_positions=[0.15, -0.3],
            expected_visibility=123.0,
        )
    if name == 'DispatchPlan':
        p = m.DispatchPlan(first_demand_index=3, expected_fused_visibility=456.0, replan_count=2)
        p.assignments = [sample('SensorAssignment')]
        return p
    if name == 'CaptureRequest':
        r = m.CaptureRequest(demand_index=3, camera_ids=['cam1', 'cam2', 'cam3'])
        r.demand_instant.sec = 12
        r.predicted_normal.y = -1.0
        return r
    if name == 'MarkerObservation':
        o = m.MarkerObservation(
            camera_id='cam2',
            demand_index=3,
            status=m.MarkerObservation.STATUS_NOT_FOUND,
            reason='no marker in the image',
        )
        o.ellipse = sample('Ellipse')
        o.covariance[35] = 2e-5
        return o
    if name == 'TargetEstimate':
        e = m.TargetEstimate(
            demand_index=3,
            status=m.TargetEstimate.STATUS_OK,
            cameras_used=['cam1', 'cam3', 'cam4'],
            cameras_faulty=['cam2'],
        )
        e.position.x = 0.2
        e.region_lower[0] = 0.199
        e.region_upper[0] = 0.201
        return e
    if name == 'StageGoal':
        return m.StageGoal(
            joint_names=['cam1_x', 'cam1_yaw'], positions=[0.1, 0.2], max_velocities=[0.025, 0.2]
        )
    if name == 'ObjectState':
        s = m.ObjectState(in_workspace=True)
        s.side_marker.x = 0.3
        s.side_normal.y = -1.0
        return s
    raise KeyError(name)


def main() -> int:
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    import activesurv_interfaces.msg as m

    qos = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    rclpy.init()
    node = rclpy.create_node('sample_publisher')
    pubs = {n: node.create_publisher(getattr(m, n), f'sample/{n}', qos) for n in MESSAGE_TYPES}
    try:
        while rclpy.ok():
            for name, pub in pubs.items():
                pub.publish(sample(name))
            rclpy.spin_once(node, timeout_sec=0.2)
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
