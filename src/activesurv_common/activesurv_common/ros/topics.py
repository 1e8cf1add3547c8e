"""Every topic name of the graph, in one place (relative names unless global by nature).

Camera topics are prefixed by the camera id (``cam1/image_raw``); the functions build them.
"""

from __future__ import annotations

# Ground truth and time (simulator)
OBJECT_STATE = 'object_state'
CLOCK = '/clock'
# Simulation only: the owner of /clock's mapping, simulated time = (steady time - data[0]) *
# data[1] (std_msgs/Float64MultiArray, latched), so nodes on its host read the time exactly.
CLOCK_ORIGIN = '/sim/clock_origin'
TIME_RELEASE = '/sim/time_release'  # latched std_msgs/Empty: a held simulated time may start
# latched std_msgs/String per node: its name once its topics are matched (ros.ready)
READY = 'activesurv/ready'
# Simulation only: the truth at a demand instant as already determined before it (the table's
# programmed path; a stage's motion when no new goal comes), so a simulated camera can render
# ahead what it will expose. Real drivers publish nothing of the kind.
PLANNED_OBJECT_STATE = 'sim/planned_object_state'
# The table's states around requested instants only (a camera imaging on requests needs no more).
INSTANT_OBJECT_STATE = 'sim/instant_object_state'
# Prediction
OVERHEAD_FIX = 'overhead/fix'
OVERHEAD_FIXES = 'overhead/fixes'  # several objects: every top marker of a frame
OVERHEAD_TRACK = 'overhead/track'
OBJECT_TRACKS = 'object_tracks'
OBJECT_TRACK_MARKERS = 'object_track_markers'
DEMAND_HORIZON = 'demand_horizon'
# Dispatch
DISPATCH_PLAN = 'dispatch_plan'
DISPATCH_MARKERS = 'dispatch_markers'
CAPTURE_REQUEST = 'capture_request'
# Imaging and fusion
MARKER_OBSERVATIONS = 'marker_observations'
TARGET_ESTIMATE = 'target_estimate'
TARGET_POSE = 'target_pose'
# Infrastructure
DIAGNOSTICS = '/diagnostics'
ESTOP = 'estop'  # the rig's e-stop (std_msgs/Bool, latched): <namespace>/estop
TF = '/tf'
TF_STATIC = '/tf_static'
RECORDER_STATUS = '/activesurv/recorder_status'
RUN_INFO = '/activesurv/run_info'

OVERHEAD = 'overhead'
"""The overhead camera's id (its topics are ``overhead/image_raw`` etc.)."""


def image(camera_id: str) -> str:
    return f'{camera_id}/image_raw'


def camera_info(camera_id: str) -> str:
    return f'{camera_id}/camera_info'


def preview(camera_id: str) -> str:
    """A free-running image stream for viewers (sensor_msgs/Image; not imaged, not recorded)."""
    return f'{camera_id}/preview/image_raw'


def marker_annotations(camera_id: str) -> str:
    """The imager's drawing over its image (visualization_msgs/ImageMarker)."""
    return f'{camera_id}/marker_annotations'


def demand_frame(camera_id: str) -> str:
    """The frame an imager measured for a demand (sensor_msgs/CompressedImage, PNG): what a
    hardware run records to look at and replay (``--record-frames used``)."""
    return f'{camera_id}/demand_frame'


def heartbeat(camera_id: str) -> str:
    """The imager's liveness beat (std_msgs/Header, frame_id = camera id, 10 Hz)."""
    return f'{camera_id}/imager/heartbeat'


def joint_states(camera_id: str) -> str:
    return f'{camera_id}/stage/joint_states'


def planned_joint_states(camera_id: str) -> str:
    """Simulation only: a stage's state at a coming demand instant, if no new goal comes."""
    return f'sim/{camera_id}/planned_joint_states'


def goal(camera_id: str) -> str:
    return f'{camera_id}/stage/goal'
