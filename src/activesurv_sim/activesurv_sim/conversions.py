"""Conversions between the simulator's truth and messages."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from builtin_interfaces.msg import Time

from activesurv_common.camera_model import CameraModel, dynamic_camera, overhead_camera
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_interfaces.msg import ObjectState as ObjectStateMsg
from activesurv_sim.render import SensorNoise
from activesurv_sim.sim_camera import ObjectGeometry, SimulatedCamera
from activesurv_sim.xytable import ObjectState


def object_state_msg(state: ObjectState, stamp: Time, frame_id: str) -> ObjectStateMsg:
    msg = ObjectStateMsg()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.top_marker.x, msg.top_marker.y, msg.top_marker.z = (float(v) for v in state.top)
    msg.side_marker.x, msg.side_marker.y, msg.side_marker.z = (float(v) for v in state.side)
    n = state.side_normal
    msg.side_normal.x, msg.side_normal.y, msg.side_normal.z = (float(v) for v in n)
    msg.velocity.x, msg.velocity.y, msg.velocity.z = (float(v) for v in state.velocity)
    msg.in_workspace = bool(state.present)
    return msg


def simulated_camera(p: Mapping[str, Any], mount: CameraMount | Transform) -> SimulatedCamera:
    """The simulated camera of a ``sim_camera`` node's parameters ``p`` on ``mount``."""
    camera_id = str(p['camera_id'])
    if p['intrinsics_file']:
        model = CameraModel.load(str(p['intrinsics_file']))
    elif p['camera_type'] == 'overhead':
        model = overhead_camera(camera_id)
    else:
        model = dynamic_camera(camera_id)
    return SimulatedCamera(
        model,
        mount,
        ObjectGeometry(
            float(p['side_marker_radius']),
            float(p['top_marker_radius']),
            float(p['plate_half_size']),
        ),
        SensorNoise(
            float(p['blur_sigma']),
            float(p['electrons_per_level']),
            float(p['read_noise']),
            int(p['supersample']),
        ),
        int(p['seed']),
    )
