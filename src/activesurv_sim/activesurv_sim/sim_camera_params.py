"""Parameters of the ``sim_camera`` node (``config/sim_camera.yaml`` is generated from them)."""

from __future__ import annotations

from activesurv_common.occlusion import PLATE_HALF_SIZE
from activesurv_common.ros.parameters import Param

PARAMS = (
    Param('camera_id', 'cam1', 'camera id (topic prefix)'),
    Param(
        'camera_type',
        'dynamic',
        'default optics: dynamic (25 mm) or overhead (12 mm)',
        choices=('dynamic', 'overhead'),
    ),
    Param('intrinsics_file', '', 'camera YAML (camera_calibration layout); overrides the type'),
    Param(
        'rig_file',
        '',
        "rig YAML: the camera's true optics, mount and stage errors (override the above)",
    ),
    Param(
        'camera_info_file',
        '',
        'camera_info to publish (the calibration, as a driver does); empty: the true optics',
    ),
    Param(
        'payload',
        'object',
        "what the table carries: the object's markers, or the commissioning boards",
        choices=('object', 'board'),
    ),
    Param('frame_rate', 0.0, 'free-running Hz; 0: triggered by capture requests', minimum=0.0),
    Param('frame_phase', 0.0, 'free-running: frames at states stamped phase + n / frame_rate'),
    Param(
        'preview_rate',
        0.0,
        'Hz of a free-running preview on <cam>/preview/image_raw for viewers (not imaged)',
        minimum=0.0,
    ),
    Param(
        'instant_states',
        False,
        "the table's states around requested instants only (sim/instant_object_state), not "
        'every object_state: for a camera imaging on requests (frame_rate, preview_rate 0)',
    ),
    Param('trigger_delay', 0.0, 'min s from a demand instant to its frame', minimum=0.0),
    Param('state_hold', 0.2, 's a state may be extrapolated', minimum=0.0),
    Param('seed', 0, 'image noise seed'),
    Param('side_marker_radius', 0.0125, 'side marker radius (m)', above=0.0),
    Param('top_marker_radius', 0.0125, 'top marker radius (m)', above=0.0),
    Param('plate_half_size', PLATE_HALF_SIZE, 'half side of the marker plates (m)', above=0.0),
    Param('blur_sigma', 0.8, 'lens blur (px)', minimum=0.0),
    Param('electrons_per_level', 40.0, 'shot noise scale', above=0.0),
    Param('read_noise', 1.0, 'read noise (grey levels)', minimum=0.0),
    Param('supersample', 8, 'edge supersampling per axis', minimum=1, maximum=16),
    Param('inject_frozen', False, 'fault: keep sending the first frame'),
    Param('render_ahead', True, 'render a requested frame when its truth is planned'),
    Param('own_trigger', True, 'a frame rendered ahead goes out at its instant, own clock'),
    Param(
        'remote_delay',
        0.03,
        's a demand frame imaged in process waits before its DDS copy (bag, viewers); 0: none',
        minimum=0.0,
        maximum=1.0,
    ),
)
