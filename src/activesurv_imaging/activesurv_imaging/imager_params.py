"""The ``imager`` node's parameters (``config/imager.yaml`` is generated from them): typed
defaults, descriptions with units, bounds. Named as :class:`~activesurv_imaging.capture.
ImagerConfig`'s fields, plus the camera's intrinsics source and its mount."""

from __future__ import annotations

from activesurv_common.ros.conversions import MOUNT_PARAMETERS
from activesurv_common.ros.parameters import Param
from activesurv_imaging.imager_config import TRIGGERS

PARAMS = (
    Param('camera_id', 'cam1', 'camera this imager serves'),
    Param('marker_radius', 0.0125, 'side marker radius (m)', above=0.0),
    Param('sensor_model_file', '', 'sensor model YAML; empty: the packaged model'),
    Param('frame_tolerance', 0.005, 'max |frame stamp - demand instant| (s)', above=0.0),
    Param('frame_timeout', 1.0, 's after the demand instant to wait for a frame', above=0.0),
    Param('joint_hold', 0.2, 's a stage state may be held beyond its stamp', above=0.0),
    Param('reliable_images', False, 'images and stage states reliably (publishers must be)'),
    Param('exact_states', False, 'wait for a stage state stamped at the frame (trigger latch)'),
    Param('trigger', 'hardware', 'how the camera exposes', choices=TRIGGERS),
    Param('frame_rate', 0.0, 'Hz of a free-running camera', minimum=0.0),
    Param('exposure_delay', 0.0, 's from exposure to the frame stamp', minimum=0.0),
    Param(
        'exposure_time',
        0.0,
        "s the shutter is open (a moving marker's streak is taken out); 0: the calibration's",
        minimum=0.0,
        maximum=1.0,
    ),
    Param(
        'gamma',
        0.0,
        "the camera's response, grey = 255 radiance^(1/gamma), undone before edges are "
        "measured; 0: the calibration's (camera_info carries none)",
        minimum=0.0,
        maximum=5.0,
    ),
    Param('motion_correction', True, "move a free-running frame's marker to the instant"),
    Param('free_reach', 3.25, 'free-running: periods the taken frame may be off', minimum=0.5),
    Param('velocity_std', 0.002, 'm/s: what the motion correction does not know', minimum=0.0),
    Param('pointing_std', 1e-4, 'rad: calibration pointing error', minimum=0.0, maximum=0.1),
    Param('obstacles_file', '', "YAML with the cell's obstacles (a rig or set-up file)"),
    Param('several_objects', False, 'measure the marker nearest the predicted one of several'),
    Param('inject_bias_x', 0.0, 'fault: m added to world x'),
    Param('inject_noise', 0.0, 'fault: extra position std (m)', minimum=0.0),
    Param('inject_flip', False, 'fault: take the wrong circle pose'),
    Param(
        'camera_info_file',
        '',
        'commissioned intrinsics (camera_calibration YAML); used over the camera_info topic',
    ),
    Param(
        'camera_info_tolerance',
        2.0,
        'px: a camera_info that disagrees more with camera_info_file is warned about',
        above=0.0,
    ),
    Param(
        'trigger_service',
        '',
        "trigger software: the driver's std_srvs/Trigger service, called before each instant",
    ),
    Param(
        'trigger_lead', 0.001, 's the trigger service is called before the instant', minimum=0.0
    ),
    Param('record_frames', False, 'publish the frame of each demand (PNG) on <cam>/demand_frame'),
    Param(
        'viewers_delay',
        0.03,
        "s after an observation before its annotations and frame go out (the other cameras' "
        'imaging first); 0: at once',
        minimum=0.0,
        maximum=1.0,
    ),
    # The camera's mount (what a hand-started imager needs: commissioning writes them).
    *(Param(name, default, text) for name, (default, text) in MOUNT_PARAMETERS.items()),
)
