"""Conversions between the simulator's truth and messages."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from activesurv_common.camera_model import CameraModel, dynamic_camera, overhead_camera
from activesurv_common.errors import CalibrationError
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.ros import topics
from activesurv_sim.board import BoardFixture
from activesurv_sim.board_scene import board_scene
from activesurv_sim.errors import SimError
from activesurv_sim.render import Scene, SensorNoise
from activesurv_sim.rig import load_rig
from activesurv_sim.sim_camera import SimulatedCamera

# What a lab camera logs once it is up (the lab reports ready when every camera has).
DRIVER_UP = 'camera driver up'


def simulated_camera(p: Mapping[str, Any], mount: CameraMount | Transform) -> SimulatedCamera:
    """The simulated camera of a ``sim_camera`` node's parameters ``p`` on ``mount``.

    With ``rig_file`` the rig's truth replaces ``mount`` and the optics: its intrinsics, its
    mount with the stages' position errors (or the overhead camera's pose).
    """
    camera_id = str(p['camera_id'])
    rig = load_rig(str(p['rig_file'])) if p.get('rig_file') else None
    scene_of = None
    if p.get('payload') == 'board':
        fixture, offset = BoardFixture(), rig.table_offset if rig is not None else None

        def scene_of(state: NDArray[np.float64]) -> Scene:
            xy = state[:2] + (offset(float(state[0]), float(state[1])) if offset else 0.0)
            return board_scene(fixture, xy)

    optics = None  # without a rig: a pinhole's frames
    if rig is not None:
        if camera_id == 'overhead':
            model, mount, optics = rig.overhead, rig.overhead_pose, rig.overhead_lens
        else:
            rc = rig.camera(camera_id)
            model, mount, optics = rc.camera, rc.true_mount(), rc.lens
    elif p['intrinsics_file']:
        model = CameraModel.load(str(p['intrinsics_file']))
    elif p['camera_type'] == 'overhead':
        model = overhead_camera(camera_id)
    else:
        model = dynamic_camera(camera_id)
    return SimulatedCamera(
        model,
        mount,
        ObjectGeometry(
            side_radius=float(p['side_marker_radius']),
            top_radius=float(p['top_marker_radius']),
            plate_half_size=float(p['plate_half_size']),
        ),
        SensorNoise(
            float(p['blur_sigma']),
            float(p['electrons_per_level']),
            float(p['read_noise']),
            int(p['supersample']),
        ),
        int(p['seed']),
        scene_of,
        rig.obstacles if rig is not None else (),
        optics,
    )


def object_topic(p: Mapping[str, Any]) -> str:
    """The object states a simulated camera with parameters ``p`` subscribes to: every state
    (``object_state``), or, with ``instant_states``, those around requested instants
    (``sim/instant_object_state``, :mod:`activesurv_sim.instant_window`).

    Raises:
        SimError: for ``instant_states`` with a free-running stream or previews, which render
            at every state.
    """
    if not bool(p.get('instant_states', False)):
        return topics.OBJECT_STATE
    if float(p.get('frame_rate', 0.0)) > 0.0 or float(p.get('preview_rate', 0.0)) > 0.0:
        raise SimError(
            'instant_states is for a camera imaging on requests only: it needs '
            'frame_rate and preview_rate 0'
        )
    return topics.INSTANT_OBJECT_STATE


def published_model(p: Mapping[str, Any], sim: SimulatedCamera) -> CameraModel:
    """What the camera's driver says about its optics on ``camera_info``: the calibration
    (``camera_info_file``) when given, else the true optics.

    Raises:
        CalibrationError: for an unreadable file or one of another image size.
    """
    if not p.get('camera_info_file'):
        return sim.camera
    model = CameraModel.load(str(p['camera_info_file']))
    if (model.width, model.height) != (sim.camera.width, sim.camera.height):
        raise CalibrationError(
            f'{p["camera_info_file"]}: {model.width}x{model.height} calibration for a '
            f'{sim.camera.width}x{sim.camera.height} camera'
        )
    return model
