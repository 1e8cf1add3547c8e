"""``activesurv commission``: calibrate the rig through the node graph, as a lab would.

Over the same topics a real rig has: each camera's stage takes ``<cam>/stage/goal`` and reports
``<cam>/stage/joint_states``; the xy table is a two-axis stage (``xy_table/stage/goal``, joints
``table_x``, ``table_y``) carrying the boards (:class:`activesurv_sim.board.BoardFixture`);
cameras publish ``<cam>/image_raw`` and ``camera_info`` and are triggered by
``capture_request``. The procedure (:func:`activesurv_bringup.rig.board_views.collect_stations`)
moves stages and table, waits for them to settle, captures and finds the board; then
:mod:`activesurv_imaging.commissioning` fits each camera, and the overhead camera's mapping
comes from the top board over a grid of table positions.

In simulation (``--rig``) the graph is simulated stages and cameras playing the rig (wall
clock); with ``--live`` the commissioner talks to whatever runs (``stage_bridge`` nodes, camera
drivers). It writes ``CALDIR/<camera>.yaml``, ``<camera>_mount.yaml``, ``overhead.yaml``,
``overhead_pose.yaml`` and ``commission.json`` (per camera the reprojection RMS, and in
simulation each estimate's error against the rig).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.files import new_output_dir
from activesurv_bringup.observer import Observer
from activesurv_bringup.rig.board_views import (
    Look,
    board_corners,
    collect_stations,
    simulated_look,
    simulated_overhead_look,
)
from activesurv_bringup.rig.rigs import layout_file, nominal
from activesurv_bringup.specs import bridge_spec, source_specs, stage_spec
from activesurv_common.calibration import Calibration
from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_common.ros import topics
from activesurv_common.trigger import SourceKind
from activesurv_dispatch.sensors import Setup, load_setup
from activesurv_hardware.hardware_file import Hardware
from activesurv_imaging.calibration import board_points, find_corners
from activesurv_imaging.commissioning import (
    BoardSighting,
    c1_offset,
    commission_camera,
    order_like,
    pixel_error,
)
from activesurv_imaging.errors import CalibrationError
from activesurv_imaging.response import BoardReader, GammaEstimate
from activesurv_launch.launcher import Launcher, NodeSpec
from activesurv_launch.session import GraphSession
from activesurv_sim.board import BoardFixture
from activesurv_sim.rig import Rig, save_rig
from activesurv_sim.xytable import TABLE_ID, TABLE_JOINTS, TABLE_RANGE

Array = NDArray[np.float64]
Progress = Callable[[str], None]
C1_TURN = 0.02  # rad: keeps a centred board whole in a 7-degree view
OVERHEAD_GRID = ((0.05, 0.15, 0.25, 0.35, 0.45), (0.02, 0.10, 0.18))


def commission_specs(rig_file: Path, setup: Setup, nominal_dir: Path) -> list[NodeSpec]:
    """Simulated stages, table and cameras playing the rig (wall clock, Table I speeds)."""
    wall = {'use_sim_time': False}
    specs = [
        NodeSpec(
            'xy_table_stage',
            'activesurv_sim.sim_stage_node',
            parameters={
                **wall,
                'camera_id': TABLE_ID,
                'joints': list(TABLE_JOINTS),
                'kinds': ['linear', 'linear'],
                'min': [TABLE_RANGE[0][0], TABLE_RANGE[1][0]],
                'max': [TABLE_RANGE[0][1], TABLE_RANGE[1][1]],
                'initial': [0.25, 0.10],
                'motion_class': 'hardware',
                'publish_rate': 20.0,
            },
        ),
        camera_spec('overhead', rig_file, nominal_dir, {'camera_type': 'overhead'}),
    ]
    for i, s in enumerate(setup.sensors):
        cid = s.camera_id
        specs.append(stage_spec(s, setup.initial[cid], 'hardware', 20.0, sim_time=False))
        specs.append(camera_spec(cid, rig_file, nominal_dir, {'seed': 500 + i}))
    return specs


def camera_spec(cid: str, rig_file: Path, nominal_dir: Path, extra: dict[str, Any]) -> NodeSpec:
    return NodeSpec(
        f'{cid}_camera',
        'activesurv_sim.sim_camera_node',
        parameters={
            'use_sim_time': False,
            'camera_id': cid,
            'payload': 'board',
            'rig_file': str(rig_file),
            # the driver's factory calibration: nominal optics
            'camera_info_file': str(nominal_dir / f'{cid}.yaml'),
            'frame_rate': 0.0,
            'render_ahead': False,
            'state_hold': 1.0,
            **extra,
        },
    )


class Commissioner(Observer):
    """Drives stages and table, triggers cameras and collects what they see (the
    orchestrator's :class:`~activesurv_bringup.observer.Observer`, used in a ``with`` block)."""

    def __init__(
        self,
        setup: Setup,
        cameras: Sequence[str],
        settle_timeout: float = 20.0,
        image_topics: dict[str, tuple[str, str]] | None = None,
        namespace: str = '',
        triggers: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__('commissioner', namespace)
        self.setup = setup
        self.cameras = list(cameras)
        self.settle_timeout = settle_timeout
        self._image_topics = image_topics or {}
        self._trigger_services = dict(triggers or {})

    def on_start(self) -> None:
        self.watch_stages([TABLE_ID, *self.cameras])
        for cid in ['overhead', *self.cameras]:
            image, info = self._image_topics.get(cid, (topics.image(cid), topics.camera_info(cid)))
            self.watch_camera(cid, image, info, self._trigger_services.get(cid, ''))

    def hold(
        self, runner: Launcher, specs: Sequence[NodeSpec], startup_timeout: float
    ) -> GraphSession:
        """The graph this commissioner drives: up once every stage's joint states are heard;
        Ctrl-C unwinds it at once (nothing to finish), the nodes stopped all the same."""
        return GraphSession(
            runner,
            specs,
            self.missing_stages,
            self.spin,
            startup_timeout,
            settle=0.0,
            trap_signals=False,
        )

    def look(
        self, camera_id: str, fixture: BoardFixture, reader: BoardReader | None = None
    ) -> Look:
        names = self.setup.sensor(camera_id).joint_names
        read = reader or BoardReader(fixture.squares)

        def look(q: Array, x: float, y: float) -> Array | None:
            self.move(camera_id, names, q)
            self.move(TABLE_ID, TABLE_JOINTS, np.array([x, y]))
            return read(self.capture(camera_id, (camera_id, TABLE_ID)))

        return look

    def look_overhead(self, fixture: BoardFixture) -> Callable[[float, float], Array | None]:
        def look(x: float, y: float) -> Array | None:
            self.move(TABLE_ID, TABLE_JOINTS, np.array([x, y]))
            return find_corners(self.capture('overhead', (TABLE_ID,)), fixture.top_squares)

        return look


def with_response(
    model: CameraModel, estimate: GammaEstimate | None
) -> tuple[CameraModel, dict[str, Any]]:
    """The camera with the response its board edges showed (the report's ``response``); kept
    as it was when too few edges were blurred enough to show it (all views in focus), or when
    the estimate is within :data:`LINEAR_BAND` of linear: the estimator reads 1-3 % low, and a
    linear camera told 0.98 measures a marker's depth 0.1 mm off (docs/commissioning.md)."""
    if estimate is None:
        says = f'gamma {model.gamma:g} kept (too few blurred board edges to estimate it)'
        return model, {'gamma': None, 'kept': model.gamma, 'says': says}
    gamma = round(estimate.gamma, 3)
    report: dict[str, Any] = {
        'gamma': gamma,
        'std': round(estimate.spread, 4),
        'edges': estimate.profiles,
    }
    if not applies(estimate):
        report['kept'] = model.gamma
        report['says'] = (
            f'linear (estimate {gamma:.2f} +- {estimate.spread:.2f} from {estimate.profiles} '
            f'edges, within {LINEAR_BAND:.0%} of 1): gamma {model.gamma:g} kept'
        )
        return model, report
    report['says'] = f'gamma {gamma:.2f} +- {estimate.spread:.2f} from {estimate.profiles} edges'
    return replace(model, gamma=gamma), report


LINEAR_BAND = 0.1  # an estimated gamma within this of 1 is a linear camera's


def applies(estimate: GammaEstimate | None) -> bool:
    """Whether a response estimate says the camera is not linear (it is then used)."""
    return estimate is not None and abs(estimate.gamma - 1.0) > LINEAR_BAND


def commission_dynamic(
    look: Look,
    start: CameraModel,
    nominal_mount: CameraMount,
    fixture: BoardFixture,
    stations_limit: int | None = None,
    reader: BoardReader | None = None,
) -> tuple[CameraModel, CameraMount, dict[str, Any]]:
    """One dynamic camera: stations, fit, and the eq. C1 check; returns (model, mount, report).

    Args:
        look: shows the board at a table position to the camera at stage positions.
        start: the intrinsics to start from (what the driver says, or nominal).
        nominal_mount: the mount as designed.
        stations_limit: at most this many stations (None: every one of the procedure).
        reader: the views ``look`` went through: with a response estimated from them (a
            gamma other than 1), every corner is refined again in linear radiance.
    """
    stations = collect_stations(look, start, nominal_mount, fixture, limit=stations_limit)
    estimate = reader.gamma() if reader is not None else None
    if reader is not None:
        reader.keeping = False  # the eq. C1 check's views: not the estimate's
    if reader is not None and estimate is not None and applies(estimate):
        g = estimate.gamma
        stations = [
            replace(
                st,
                sightings=tuple(
                    replace(v, corners=reader.linearised(v.corners, g)) for v in st.sightings
                ),
            )
            for st in stations
        ]
    board = board_corners(fixture)
    fit = commission_camera(start, nominal_mount, stations, board)
    model, mount = fit.camera, fit.mount
    report: dict[str, Any] = {
        'reprojection_rms_px': fit.rms,
        'corner_noise_px': fit.noise.corner,
        'sighting_noise_px': fit.noise.sighting,
        # one standard deviation, from the noise model (what the views carry)
        'std': {
            'focal_length_relative': float(fit.std[0] / model.fx),
            'principal_point_px': [float(fit.std[2]), float(fit.std[3])],
            'base_m': [float(v) for v in fit.std[5:8]],
            'rotation_centre_offset_m': [float(v) for v in fit.std[10:12]],
        },
        'stations': len(stations),
        'sightings': sum(len(s.sightings) for s in stations),
        'sightings_dropped': fit.dropped,  # outliers left out of the fit
    }
    # Eq. C1 (Appendix C), the paper's check: the board fixed, the camera turned by 0.02 rad.
    middle = [st for st in stations if st.sightings][len(stations) // 2 :][:1]
    pairs = []
    for st in middle:
        T_cam = mount.pose_from_joints(st.joints).inverse()
        centre = np.array([model.cx, model.cy])
        centred = sorted(
            st.sightings, key=lambda s: float(np.linalg.norm(s.corners.mean(axis=0) - centre))
        )
        for sighting in centred[:3]:  # the turn moves the image by ~100 px: keep it whole
            T = sighting.T_world_board
            x, y = float(T.t[0] - fixture.offset[0]), float(T.t[1] - fixture.offset[1])
            turned = st.joints.copy()
            turned[-1] += C1_TURN
            before, after = look(st.joints, x, y), look(turned, x, y)
            if before is None or after is None:
                continue
            expected = model.project((board @ T.R.T + T.t) @ T_cam.R.T + T_cam.t)
            pairs.append(
                (
                    BoardSighting(T, order_like(before, expected)),
                    BoardSighting(T, order_like(after, expected)),
                    C1_TURN,
                )
            )
    try:
        rco = c1_offset(pairs, model, board, mount.pitch)
        report['c1_rotation_centre_offset'] = [float(v) for v in rco]
    except CalibrationError as exc:
        report['c1_rotation_centre_offset'] = None
        report['c1_note'] = str(exc)
    report['joints'] = [[float(v) for v in st.joints] for st in stations]
    return model, mount, report


def commission_overhead(
    look: Callable[[float, float], Array | None],
    nominal: CameraModel,
    nominal_pose: Transform,
    fixture: BoardFixture,
) -> tuple[CameraModel, Transform, dict[str, Any]]:
    """The overhead camera from the top board over a grid of table positions: one planar
    target at the top markers' height. Looking straight down at one plane, focal length and
    height trade exactly (only f/Z is seen) and the principal point trades with the tilt, so
    those stay nominal and the pose and k1 take up the rest: what the overhead locator needs
    is the image-to-table mapping at the markers' height, and that is what is fitted."""

    top = board_points(fixture.top_squares, fixture.top_square_size)
    plane_pts, image_pts = [], []
    Tc = nominal_pose.inverse()
    for x in OVERHEAD_GRID[0]:
        for y in OVERHEAD_GRID[1]:
            corners = look(x, y)
            if corners is None:
                continue
            T = fixture.top_pose(x, y)
            world = top @ T.R.T + T.t
            corners = order_like(corners, nominal.project(world @ Tc.R.T + Tc.t))
            plane_pts.append(world - [0.0, 0.0, fixture.top_height])
            image_pts.append(corners)
    if len(plane_pts) < 4:
        raise CalibrationError(f'the overhead camera found the top board {len(plane_pts)} times')
    obj = np.vstack(plane_pts).astype(np.float32)
    img = np.vstack(image_pts).astype(np.float32).reshape(-1, 1, 2)
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_PRINCIPAL_POINT
        | cv2.CALIB_FIX_FOCAL_LENGTH
        | cv2.CALIB_ZERO_TANGENT_DIST
        | cv2.CALIB_FIX_K2
        | cv2.CALIB_FIX_K3
    )
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [obj], [img], (nominal.width, nominal.height), nominal.K.copy(), np.zeros(5), flags=flags
    )
    R, _ = cv2.Rodrigues(rvecs[0])
    T_cam_plane = Transform(
        np.asarray(R, dtype=np.float64), np.asarray(tvecs[0], dtype=np.float64).reshape(3)
    )
    plane = Transform(np.eye(3), np.array([0.0, 0.0, fixture.top_height]))
    pose = plane.compose(T_cam_plane.inverse())
    model = CameraModel(
        nominal.width,
        nominal.height,
        np.asarray(K, dtype=np.float64),
        np.asarray(dist, dtype=np.float64).reshape(-1)[:5],
        'overhead',
    )
    return model, pose, {'reprojection_rms_px': float(rms), 'sightings': len(plane_pts)}


def errors_against(
    rig: Rig, cid: str, model: CameraModel, mount: CameraMount, joints: Sequence[Array]
) -> dict[str, float]:
    """Each estimate against the rig (simulation only)."""
    t = rig.camera(cid)
    return {
        'focal_length_relative': float(abs(model.fx / t.camera.fx - 1.0)),
        'principal_point_px': float(np.max(np.abs(model.K[:2, 2] - t.camera.K[:2, 2]))),
        'principal_point_x_px': float(model.cx - t.camera.cx),  # signed
        'principal_point_y_px': float(model.cy - t.camera.cy),
        'k1': float(abs(model.dist[0] - t.camera.dist[0])),
        'base_m': float(np.max(np.abs(mount.base - t.mount.base))),
        'rotation_centre_offset_m': float(np.max(np.abs(mount.offset - t.mount.offset))),
        'yaw_offset_rad': float(abs(mount.yaw_offset - t.mount.yaw_offset)),
        'pitch_rad': float(abs(mount.pitch - t.mount.pitch)),
        'pixel_error_px': max(
            pixel_error(t.camera, t.true_mount(), model, mount, q) for q in joints
        )
        if joints
        else math.nan,
    }


def plane_mapping_error(
    truth: CameraModel, true_pose: Transform, model: CameraModel, pose: Transform, z: float
) -> float:
    """Largest distance (m) over the table between where points of the plane at height ``z``
    are and where the calibrated camera maps their pixels back onto that plane."""
    x, y = np.meshgrid(np.linspace(0.0, 0.5, 11), np.linspace(0.0, 0.2, 5))
    world = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
    Tt = true_pose.inverse()
    px = truth.project(world @ Tt.R.T + Tt.t)
    rays = model.rays(px) @ pose.R.T  # world directions
    lam = (z - pose.t[2]) / rays[:, 2]
    back = pose.t + lam[:, None] * rays
    return float(np.max(np.linalg.norm(back[:, :2] - world[:, :2], axis=1)))


def write_calibration(out: Path, cal: Calibration, report: dict[str, Any]) -> Path:
    """The calibration files and ``commission.json`` into ``out``."""
    cal.save(out)
    path = out / 'commission.json'
    path.write_text(json.dumps(report, indent=2) + '\n')
    return path


def check_cameras(setup: Setup, cameras: Sequence[str] | None) -> list[str]:
    known = [s.camera_id for s in setup.sensors]
    chosen = list(cameras) if cameras else known
    unknown = sorted(set(chosen) - set(known))
    if unknown:
        raise ConfigError(f'no camera {unknown} in the set-up; it has {known}')
    return chosen


def commission_all(
    dynamic: Callable[[str, BoardReader], tuple[Look, CameraModel]],
    overhead_look: Callable[[float, float], Array | None],
    all_cameras: Sequence[str],
    chosen: Sequence[str],
    rig: Rig | None,
    progress: Progress,
    name: str,
    stations: int | None = None,
    layout: Path | None = None,
    fixture: BoardFixture | None = None,
) -> tuple[Calibration, dict[str, Any]]:
    """Commission ``chosen`` cameras (the rest keep nominal values) and the overhead camera.

    Args:
        dynamic: per camera id (and the reader its views go through), how it looks at the
            board and the intrinsics to start from.
        overhead_look: the overhead camera looking at the top board at a table position.
        rig: the simulated truth, to report each estimate's error (None when live).
        stations: at most this many stations per dynamic camera (None: all).
        layout: the set-up YAML of the rig as designed (None: the paper's).
        fixture: the boards on the carriage (a hardware file's ``geometry.board``; None: the
            simulator's).
    """
    nominal_cal = nominal(layout).truth()
    fixture = fixture or BoardFixture()
    models = dict(nominal_cal.cameras)
    mounts = dict(nominal_cal.mounts)
    report: dict[str, Any] = {'rig': None if rig is None else rig.name, 'cameras': {}}
    for cid in all_cameras:
        if cid not in chosen:
            report['cameras'][cid] = {'commissioned': False, 'reprojection_rms_px': None}
            continue
        t0 = time.monotonic()
        reader = BoardReader(fixture.squares)
        look, start = dynamic(cid, reader)
        model, mount, rep = commission_dynamic(
            look, start, nominal_cal.mounts[cid], fixture, stations, reader
        )
        model, rep['response'] = with_response(model, reader.gamma())
        models[cid], mounts[cid] = model, mount
        rep['commissioned'] = True
        rep['seconds'] = round(time.monotonic() - t0, 1)
        joints = [np.array(q) for q in rep.pop('joints')]
        if rig is not None:
            rep['error'] = errors_against(rig, cid, model, mount, joints)
        report['cameras'][cid] = rep
        progress(
            f'{cid}: {rep["sightings"]} board views at {rep["stations"]} stations, '
            f'reprojection RMS {rep["reprojection_rms_px"]:.3f} px, response '
            f'{rep["response"]["says"]}, {rep["seconds"]:.0f} s'
        )
    over, pose, rep = commission_overhead(
        overhead_look, nominal_cal.overhead, nominal_cal.overhead_pose, fixture
    )
    if rig is not None:
        rep['error'] = {
            'table_mapping_m': plane_mapping_error(
                rig.overhead, rig.overhead_pose, over, pose, fixture.top_height
            )
        }
    report['overhead'] = rep
    progress(f'overhead: reprojection RMS {rep["reprojection_rms_px"]:.3f} px')
    return Calibration(name, models, mounts, over, pose), report


def commission_offline(
    rig: Rig, progress: Progress = lambda _: None
) -> tuple[Calibration, dict[str, Any]]:
    """The same procedure on rendered views without the node graph (benchmarks, studies)."""
    nominal_cal = nominal().truth()
    fixture = BoardFixture()
    cameras = sorted(rig.cameras)
    return commission_all(
        lambda c, r: (simulated_look(rig, c, fixture, reader=r), nominal_cal.cameras[c]),
        simulated_overhead_look(rig, fixture),
        cameras,
        cameras,
        rig,
        progress,
        f'offline commissioning of {rig.name}',
    )


def run_commission(
    out: Path,
    rig: Rig | None,
    cameras: Sequence[str] | None = None,
    progress: Progress = print,
    startup_timeout: float = 60.0,
    hardware: Hardware | None = None,
    stations: int | None = None,
    home: bool = False,
) -> dict[str, Any]:
    """Commission the rig into ``out`` (new or empty); returns ``commission.json``.

    Args:
        out: the calibration directory to write.
        rig: the rig to simulate, or None for ``--live`` (stages, table and cameras already
            running, on this ROS domain).
        hardware: with ``--live``, the rig's hardware file: its stage bridges and camera
            drivers are started here, its cameras' topics listened to.
        home: home unreferenced axes when the bridges connect (``--home`` or the file's
            ``home: true``); never otherwise: an unreferenced axis then refuses its goals.
        cameras: the dynamic cameras to commission (default: all); the others keep nominal
            values, marked so in ``commission.json``.
        stations: at most this many stations per camera (default: all of the procedure).

    Raises:
        ConfigError: for unknown cameras; NodeDiedError: if the graph does not answer.
    """
    layout = None if hardware is None else layout_file(hardware.geometry.layout)
    setup = load_setup(layout, motion='fast')
    chosen = check_cameras(setup, cameras)
    new_output_dir(out)
    work = out / 'work'
    nominal_cal = nominal(layout).truth()
    nominal_cal.save(work / 'factory')  # what the camera drivers are shipped with
    specs: list[NodeSpec] = []
    if rig is not None:
        save_rig(rig, work / 'rig.yaml')
        specs = commission_specs(work / 'rig.yaml', setup, work / 'factory')
    topics_of: dict[str, tuple[str, str]] = {}
    if hardware is not None:
        home = home or hardware.home
        specs, topics_of = hardware_commission_specs(hardware, chosen, work, home)
    launcher = Launcher(specs, workdir=work / 'logs', env=dict(os.environ))  # none: --live
    ns = hardware.namespace if hardware is not None else ''
    started = time.monotonic()
    with (
        Commissioner(
            setup,
            chosen,
            image_topics=topics_of,
            namespace=ns,
            triggers=hardware_triggers(hardware) if hardware is not None else {},
        ) as com,
        com.hold(launcher, specs, startup_timeout),
    ):
        return _commission(
            com, setup, chosen, rig, hardware, nominal_cal, progress, out, stations, layout,
            started,
        )  # fmt: skip


def _commission(
    com: Commissioner,
    setup: Setup,
    chosen: Sequence[str],
    rig: Rig | None,
    hardware: Hardware | None,
    nominal_cal: Calibration,
    progress: Progress,
    out: Path,
    stations: int | None,
    layout: Path | None,
    started: float,
) -> dict[str, Any]:
    """The procedure, once every stage answers; writes the calibration, returns its report."""
    stages = [TABLE_ID, *chosen]
    progress(f'stages up: {stages}')
    # The boards the hardware file names (validated there); the simulator's otherwise.
    fixture = hardware.geometry.board if hardware is not None else BoardFixture()
    cal, report = commission_all(
        lambda c, r: (com.look(c, fixture, r), com.camera_model(c, nominal_cal.cameras[c])),
        com.look_overhead(fixture),
        [s.camera_id for s in setup.sensors],
        chosen,
        rig,
        progress,
        str(out),
        stations,
        layout,
        fixture,
    )
    report['board'] = {
        'squares': list(fixture.squares),
        'square_size': fixture.square_size,
        'top_squares': list(fixture.top_squares),
        'top_square_size': fixture.top_square_size,
    }
    report['seconds'] = round(time.monotonic() - started, 1)
    write_calibration(out, cal, report)
    return report


def hardware_triggers(hw: Hardware) -> dict[str, str]:
    """The software-triggered cameras of a hardware file: camera -> its Trigger service."""
    return {
        cam.camera_id: cam.software_trigger[0]
        for cam in [hw.overhead, *hw.cameras.values()]
        if cam.software_trigger[0]
    }


def hardware_commission_specs(
    hw: Hardware, cameras: Sequence[str], work: Path, home: bool = False
) -> tuple[list[NodeSpec], dict[str, tuple[str, str]]]:
    """The bridges and camera drivers of a hardware file, for commissioning ``cameras``; and
    each camera's image and camera_info topics (a driver's own, or our camera node's)."""
    missing = [c for c in cameras if c not in hw.cameras]
    if missing:
        raise ConfigError(f'{hw.path} has no cameras {missing} (it has {list(hw.cameras)})')
    if hw.table is None:
        raise ConfigError(
            f'{hw.path}: commissioning moves the boards on the xy table: it needs one'
        )
    ctl = work / 'controllers'
    ctl.mkdir(parents=True, exist_ok=True)
    specs: list[NodeSpec] = []
    topics_of: dict[str, tuple[str, str]] = {}
    stages = {TABLE_ID: hw.table_dict} | {c: hw.cameras[c].stages_dict for c in cameras}
    for stage, doc in stages.items():
        path = ctl / f'{stage}.yaml'
        path.write_text(yaml.safe_dump(dict(doc or {}), sort_keys=False))
        specs.append(bridge_spec(stage, str(path), home=home))
    for cam in [hw.overhead, *(hw.cameras[c] for c in cameras)]:
        nodes, _ = source_specs(cam, str(work / 'factory'))
        specs += nodes
        if cam.source.kind == SourceKind.TOPIC:
            topics_of[cam.camera_id] = (cam.source.value, cam.source.camera_info)
    if hw.namespace:
        specs = [replace(s, namespace=hw.namespace) for s in specs]
    return specs, topics_of
