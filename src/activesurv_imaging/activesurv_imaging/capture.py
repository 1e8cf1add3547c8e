"""The imager's session core: which frame and which camera pose answer each capture request.

A capture request names a demand instant ``t_j``. The answer uses the frame exposed within
``frame_tolerance`` of ``t_j`` and the camera pose at the frame's exposure, from the stage joint
states interpolated there.

Triggers (``trigger``): a ``hardware`` or ``software`` triggered camera exposes at ``t_j`` itself.
A ``free``-running camera at ``frame_rate`` exposes whenever its clock says: the frame nearest
``t_j`` is taken once a frame after ``t_j`` has come (so that the nearest is known), or at once
when the last frame before ``t_j`` lies within half a period of it (less the stamps' jitter,
``FREE_JITTER``): the next comes a period after it, farther from ``t_j``. It is within
half a frame period unless that frame was dropped; then the nearest that came is taken, up to
``free_reach`` periods away (3.25: three frames in a row lost, as when the machine stalls for ~100
ms, plus the stamps' jitter). Its offset ``frame stamp - t_j`` is reported, the marker position is
moved to ``t_j`` along the object's predicted velocity (``v (t_j - t_frame)``), and its covariance
grows by ``(velocity_std (t_j - t_frame))^2`` in x and y: what the prediction's velocity does not
know of the motion. Every reading's covariance also carries the calibration's ``pointing_std``
(:func:`with_pointing`). A frame's stamp minus ``exposure_delay`` is its exposure instant (a driver
that stamps frames on arrival stamps them after exposure and read-out).

It waits (returns nothing yet) while the frame, the camera_info or a stage state at or after
the frame's stamp is still to come, and gives up with an explicit failure ``frame_timeout``
seconds after ``t_j``: every request gets exactly one observation.
The ``imager`` node feeds it from topics; lockstep mode feeds it directly, so both modes measure
the same way.
"""

from __future__ import annotations

import math
import time
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel, dynamic_camera
from activesurv_common.geometry import Transform
from activesurv_common.mount import CameraMount
from activesurv_common.occlusion import load_obstacles, sight_blocked
from activesurv_common.sensor_model import SensorModel
from activesurv_common.statuses import ObservationStatus
from activesurv_common.timeseries import FrameBuffer, TimeSeries
from activesurv_common.trigger import Trigger
from activesurv_imaging.errors import VisionErrors
from activesurv_imaging.imager_config import ImagerConfig
from activesurv_imaging.marker_pose import measure_marker
from activesurv_imaging.observation import (
    Observation,
    failed,
    image_streak,
    observe_marker,
    perturb,
)

F = TypeVar('F')
Gray = NDArray[np.uint8]


FREE_JITTER = 0.003  # s: a free-running camera's stamps scatter by this much around its period
RECEIVED_KEPT = 64  # arrival times of the newest frames kept (the latency budget)


@dataclass(frozen=True)
class Request:
    """A capture request this camera must answer."""

    index: int
    demand_time: float
    prior_normal: NDArray[np.float64] | None
    velocity: NDArray[np.float64] | None = None
    position: NDArray[np.float64] | None = None  # the predicted marker centre (world)


class CaptureCore(Generic[F]):
    """Frames of type ``F`` (an image message, or an array) in; observations out.

    Args:
        config: measurement settings.
        mount: the camera's stage mount, or its fixed ``T_world_camera``.
        model: the sensor model (covariance of each observation).
        to_gray: turns a frame into an 8-bit grey image; may raise an imaging error.
        camera: intrinsics, if known now (else :meth:`set_camera` when camera_info arrives).
    """

    def __init__(
        self,
        config: ImagerConfig,
        mount: CameraMount | Transform,
        model: SensorModel,
        to_gray: Callable[[F], Gray],
        camera: CameraModel | None = None,
    ) -> None:
        self.config = config
        self.mount = mount
        self.model = model
        self.camera: CameraModel | None = None
        if camera is not None:
            self.set_camera(camera)
        self._to_gray = to_gray
        self._received: dict[float, float] = {}  # exposure instant: arrival
        self.frames: FrameBuffer[F] = FrameBuffer(60)
        self.joint_names = mount.joint_names if isinstance(mount, CameraMount) else ()
        self.joints = TimeSeries(max(len(self.joint_names), 1))
        self.pending: list[Request] = []
        # The camera pose of a pending demand's instant, from the stage state published ahead
        # for it: worked out then, not between the frame's arrival and its imaging.
        self._poses: dict[float, Transform] = {}
        # A stable seed per camera: the injected noise repeats from run to run.
        self._rng = np.random.default_rng(zlib.crc32(config.camera_id.encode()))

    def warm_up(self) -> None:
        """Measure a synthetic marker once, so that the first real demand does not pay for the
        pipeline's lazy set-up (imports and first calls: 50-120 ms measured at rtf 1)."""
        img = np.full((480, 640), 25, np.uint8)
        cv2.ellipse(img, (320, 240), (110, 80), 20.0, 0.0, 360.0, 230, -1, cv2.LINE_AA)
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), 0.8), dtype=np.uint8)
        cam = self.camera or dynamic_camera(self.config.camera_id)
        measure_marker(img, cam, self.config.marker_radius, np.array([0.0, 0.0, -1.0]))

    # -- inputs --------------------------------------------------------------------------
    def set_camera(self, camera: CameraModel) -> None:
        """The camera's model (its ``camera_info`` or calibration file), with what this
        imager was told of its response and exposure over what the model says (a driver's
        ``camera_info`` carries neither)."""
        c = self.config
        if c.gamma > 0.0 and c.gamma != camera.gamma:
            camera = replace(camera, gamma=c.gamma)
        if c.exposure_time > 0.0 and c.exposure_time != camera.exposure_time:
            camera = replace(camera, exposure_time=c.exposure_time)
        self.camera = camera

    def request(
        self,
        index: int,
        demand_time: float,
        prior_normal: ArrayLike | None,
        velocity: ArrayLike | None = None,
        position: ArrayLike | None = None,
    ) -> None:
        prior = _finite(prior_normal)
        self.pending.append(
            Request(index, demand_time, prior, _finite(velocity), _finite(position))
        )
        self._pose_ahead(demand_time)

    def add_frame(self, stamp: float, frame: F, received: float | None = None) -> None:
        """A frame by its stamp (its exposure instant is ``stamp - exposure_delay``);
        ``received``: when it arrived (the latency budget's frame step)."""
        exposed = stamp - self.config.exposure_delay
        self.frames.add(exposed, frame)
        if received is not None:
            self._received[exposed] = received
            if len(self._received) > RECEIVED_KEPT:
                for old in sorted(self._received)[: len(self._received) - RECEIVED_KEPT]:
                    del self._received[old]

    def add_joints(self, stamp: float, q: ArrayLike) -> bool:
        """Add a stage state; False (ignored) if it is not finite or has the wrong size."""
        if not self.joints.add(stamp, q):
            return False
        self._poses.pop(stamp, None)  # a new state of the instant (a new goal): its pose anew
        if any(r.demand_time == stamp for r in self.pending):
            self._pose_ahead(stamp)
        return True

    def _pose_ahead(self, t: float) -> None:
        """The camera pose at a pending demand's instant ``t`` now, if its stage state is."""
        if isinstance(self.mount, CameraMount) and self.joints.has(t):
            q = self.joints.at(t)
            if q is not None:
                pose = self.mount.pose_from_joints(q)
                pose.quaternion()  # for its message too
                self._poses[t] = pose

    # -- the work ------------------------------------------------------------------------
    def camera_pose(self, t: float) -> Transform | None:
        """``T_world_camera`` at ``t``, or None if no stage state covers ``t``."""
        if not isinstance(self.mount, CameraMount):
            return self.mount
        ahead = self._poses.get(t)
        if ahead is not None and self.joints.has(t):
            return ahead  # the very sample of ``t``, worked out when it came
        q = self.joints.at(t, self.config.joint_hold)
        return None if q is None else self.mount.pose_from_joints(q)

    def poll(self, now: float) -> list[Observation]:
        """Observations of the requests that can be answered at ``now``; the rest wait."""
        done: list[Observation] = []
        keep: list[Request] = []
        for r in self.pending:
            obs = self._answer(r, now)
            if obs is None:
                keep.append(r)
            else:
                done.append(replace(obs, demand_time=r.demand_time))
        self.pending = keep
        if done and self._poses:
            waiting = {r.demand_time for r in keep}
            self._poses = {t: T for t, T in self._poses.items() if t in waiting}
        return done

    def _fail(
        self, r: Request, stamp: float, status: ObservationStatus, why: str, T: Transform | None
    ) -> Observation:
        return failed(self.config.camera_id, r.index, stamp, status, why, T)

    def _answer(self, r: Request, now: float) -> Observation | None:
        c = self.config
        timed_out = now > r.demand_time + c.frame_timeout
        stamps = self.frames.stamps()
        if (
            c.trigger == Trigger.FREE
            and not timed_out
            and (not stamps or stamps[-1] < r.demand_time)
            and (not stamps or r.demand_time - stamps[-1] > 0.5 / c.frame_rate - FREE_JITTER)
        ):
            # A nearer frame may still come: wait for one exposed after t_j, unless the last
            # is within half a period of it (the next comes a period later: farther).
            return None
        hit = self.frames.closest(r.demand_time, c.tolerance)
        if hit is None:
            if not timed_out:
                return None
            near = min(stamps, key=lambda s: abs(s - r.demand_time), default=None)
            seen = '' if near is None else f' (nearest {1e3 * (near - r.demand_time):+.1f} ms)'
            why = (
                f'no frame within {c.tolerance:g} s of the demand instant '
                f'{r.demand_time:.3f} s{seen}'
            )
            return self._fail(r, r.demand_time, ObservationStatus.NO_IMAGE, why, None)
        stamp, frame = hit
        if self.camera is None:
            if not timed_out:
                return None
            why = 'no camera_info received: intrinsics unknown'
            return self._fail(r, stamp, ObservationStatus.NO_IMAGE, why, None)
        latest = self.joints.latest_time
        staged = isinstance(self.mount, CameraMount)
        if staged and not timed_out and (latest is None or latest < stamp):
            return None  # wait for a stage state at or after the frame: interpolate, not hold
        if (
            staged
            and c.exact_state
            and not timed_out
            and not self.joints.has(stamp)
            and latest is not None
            and latest < stamp + c.joint_hold
        ):
            return None  # the latched state of the instant is on its way
        T = self.camera_pose(stamp)
        if T is None:
            if timed_out or (latest is not None and latest > stamp + 1.0):
                why = f'no stage state for {self.joint_names} at {stamp:.3f} s'
                return self._fail(r, stamp, ObservationStatus.NO_CAMERA_POSE, why, None)
            return None
        started = time.thread_time()  # CPU: the work, not the waiting for a core
        try:
            gray = self._to_gray(frame)
        except VisionErrors as exc:
            return self._fail(r, stamp, ObservationStatus.REJECTED, str(exc), T)
        obs = observe_marker(
            gray,
            self.camera,
            T,
            c.marker_radius,
            self.model,
            c.camera_id,
            r.index,
            stamp,
            r.prior_normal,
            c.inject_flip,
            r.position if c.several_objects else None,
            # The marker's motion over the exposure, taken out of its ellipse.
            image_streak(self.camera, T, r.position, r.velocity) if c.motion_correction else None,
        )
        obs = replace(
            obs,
            frame_offset=stamp - r.demand_time,
            covariance=with_pointing(obs.covariance, obs.position, T.t, c.pointing_std),
        )
        if (
            obs.status in (ObservationStatus.NOT_FOUND, ObservationStatus.REJECTED)
            and c.obstacles
            and r.position is not None
            and bool(
                sight_blocked(T.t, r.position, c.obstacles, c.marker_radius, r.prior_normal)[0]
            )
        ):
            obs = replace(obs, reason=f'occluded: an obstacle stands in the way ({obs.reason})')
        if c.motion_correction and r.velocity is not None and obs.position is not None:
            dt = r.demand_time - stamp
            shift = r.velocity * dt
            cov = obs.covariance
            if cov is not None and c.velocity_std > 0.0 and dt != 0.0:
                cov = cov.copy()
                idx = np.arange(2)
                cov[idx, idx] += (c.velocity_std * dt) ** 2
            obs = replace(
                obs, position=obs.position + shift, motion_correction=shift, covariance=cov
            )
        return perturb(
            self._timed(obs, r, stamp, started), c.inject_bias_x, c.inject_noise, self._rng
        )

    def _timed(self, obs: Observation, r: Request, stamp: float, started: float) -> Observation:
        """``obs`` with its imaging's CPU time and when its frame (exposed at ``stamp``) came."""
        got = self._received.get(stamp)
        return replace(
            obs,
            compute_time=time.thread_time() - started,
            frame_received=math.nan if got is None else got - r.demand_time,
        )


def with_pointing(
    cov: NDArray[np.float64] | None,
    position: NDArray[np.float64] | None,
    camera_centre: NDArray[np.float64],
    pointing_std: float,
) -> NDArray[np.float64] | None:
    """A world covariance grown by what the camera's calibration does not know of where it
    points: ``pointing_std`` (rad) turns the measured normal (``pointing_std^2`` on each of its
    components) and moves the marker across the line of sight by ``d pointing_std``.

    The sensor model (Appendix A) was measured with the camera's pose known exactly; a
    commissioned rig knows it to its calibration (the principal point to ~1 px, 0.2 mrad), and
    a world-frame reading carries that too.
    """
    if cov is None or position is None or pointing_std <= 0.0:
        return cov
    sight = np.asarray(position, dtype=np.float64) - np.asarray(camera_centre, dtype=np.float64)
    d = float(np.linalg.norm(sight))
    if not (math.isfinite(d) and d > 0.0):
        return cov
    los = sight / d
    out = np.array(cov, dtype=np.float64, copy=True)
    out[:3, :3] += (d * pointing_std) ** 2 * (np.eye(3) - np.outer(los, los))
    out[3:, 3:] += pointing_std**2 * np.eye(3)
    return out


def _finite(v: ArrayLike | None) -> NDArray[np.float64] | None:
    a = None if v is None else np.asarray(v, dtype=np.float64)
    return a if a is not None and np.all(np.isfinite(a)) else None


def core_from_parameters(
    values: Mapping[str, Any], mount: CameraMount | Transform, to_gray: Callable[[F], Any]
) -> CaptureCore[F]:
    """The imager's core from its parameters (named as :class:`ImagerConfig`'s fields;
    ``exact_states``, ``obstacles_file``, ``sensor_model_file``, ``camera_info_file``: the
    commissioned intrinsics, which win over a driver's camera_info), warmed up.

    Raises:
        CommonError: for a missing or malformed file.
    """
    names = ImagerConfig.__dataclass_fields__
    config = ImagerConfig(
        **{k: x for k, x in values.items() if k in names},
        exact_state=bool(values['exact_states']),
        obstacles=load_obstacles(str(values['obstacles_file'])),
    )
    model = SensorModel.load(str(values['sensor_model_file']) or None)
    core = CaptureCore(config, mount, model, to_gray)
    core.warm_up()
    if values.get('camera_info_file'):
        core.set_camera(CameraModel.load(str(values['camera_info_file'])))
    return core
