"""Core of the simulated camera: render the object as it was at a given instant.

Object states (top marker, side marker, side normal) and stage joint states arrive as
time-stamped samples; a frame for instant t uses both interpolated to t, so a triggered capture
at a demand instant sees exactly the scene at that instant.

Rendering ahead: when the truth at a coming instant is already determined (the xy table's
programmed path; a stage that gets no new goal), the simulator can say so before the instant
(:meth:`SimulatedCamera.plan`), and the frame is rendered then (:meth:`render_ahead`), while
nothing waits for it. At the instant, :meth:`frame_at` hands out that frame only if the states
that really arrived for the instant match the planned ones (1 um, 1 urad); otherwise it renders
again. A frame is thus always the truth at its instant; only the work moves earlier, as the
simulated world's rendering is work a real lab's cameras do in hardware.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from activesurv_common.camera_model import CameraModel
from activesurv_common.geometry import Transform, unit
from activesurv_common.mount import CameraMount
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.occlusion import Box, Obstacle
from activesurv_common.timeseries import TimeSeries
from activesurv_sim.errors import RenderError
from activesurv_sim.frame_optics import FrameOptics
from activesurv_sim.optics import Optics, frame_optics
from activesurv_sim.render import Plate, Renderer, Scene, SensorNoise

EMPTY_LANE = np.array([100.0, 100.0, 0.08, 100.0, 99.97, 0.05, 0.0, -1.0, 0.0])  # parked
TABLE_MAX_RATE = 1.0  # m/s: faster than any table moves an object (a jump: entering, parking)
OBSTACLE_LEVEL = 120.0  # grey fixtures: neither the black plates nor the white markers
_FACETS = 16  # a cylinder's side as a prism of this many faces


def obstacle_plates(obstacles: Sequence[Obstacle]) -> tuple[Plate, ...]:
    """The faces of the cell's obstacles (one-sided, grey): boxes as six faces, cylinders as
    a 16-sided prism capped by four squares turned by 22.5 degrees (a 16-pointed disc)."""
    plates: list[Plate] = []
    for o in obstacles:
        c = np.asarray(o.centre, dtype=np.float64)
        if isinstance(o, Box):
            half = 0.5 * np.asarray(o.size, dtype=np.float64)
            for k in range(3):
                others = [j for j in range(3) if j != k]
                for sign in (-1.0, 1.0):
                    n = np.zeros(3)
                    n[k] = sign
                    x = np.zeros(3)
                    x[others[0]] = 1.0
                    y_axis = np.cross(n, x)
                    j_y = int(np.argmax(np.abs(y_axis)))
                    plates.append(
                        Plate(
                            c + n * half[k],
                            n,
                            x,
                            (float(half[others[0]]), float(half[j_y])),
                            plate_level=OBSTACLE_LEVEL,
                            one_sided=True,
                        )
                    )
            continue
        r_in = o.radius * math.cos(math.pi / _FACETS)
        side = o.radius * math.sin(math.pi / _FACETS)
        for i in range(_FACETS):
            a = 2.0 * math.pi * i / _FACETS
            n = np.array([math.cos(a), math.sin(a), 0.0])
            plates.append(
                Plate(
                    c + r_in * n,
                    n,
                    np.array([-math.sin(a), math.cos(a), 0.0]),
                    (side, 0.5 * o.height),
                    plate_level=OBSTACLE_LEVEL,
                    one_sided=True,
                )
            )
        for sign in (-1.0, 1.0):
            n = np.array([0.0, 0.0, sign])
            for i in range(4):
                a = i * math.pi / 8.0
                plates.append(
                    Plate(
                        c + n * 0.5 * o.height,
                        n,
                        np.array([math.cos(a), math.sin(a), 0.0]),
                        (r_in, r_in),
                        plate_level=OBSTACLE_LEVEL,
                        one_sided=True,
                    )
                )
    return tuple(plates)


def object_scene(
    state: ArrayLike, geometry: ObjectGeometry, extra: tuple[Plate, ...] = ()
) -> Scene:
    """Plates of the object from a 9-vector (top xyz, side xyz, side normal xyz), and
    ``extra`` plates (the cell's obstacles: :func:`obstacle_plates`)."""
    s = np.asarray(state, dtype=np.float64).reshape(9)
    side_n = unit(s[6:9], 'side normal')
    horizontal = np.cross([0.0, 0.0, 1.0], side_n)
    if np.linalg.norm(horizontal) < 1e-6:
        horizontal = np.array([1.0, 0.0, 0.0])
    return Scene(
        (
            Plate.disc(s[3:6], side_n, geometry.side_radius, geometry.plate_half_size, horizontal),
            Plate.disc(s[0:3], [0.0, 0.0, 1.0], geometry.top_radius, geometry.plate_half_size),
            *extra,
        )
    )


RELEASED_KEPT = 64
"""Frames released ahead whose table state is still to be checked (instants whose state never
came are dropped beyond it)."""


def _same(a: NDArray[np.float64], b: NDArray[np.float64], atol: float = 1e-6) -> bool:
    """``np.allclose(a, b, rtol=0, atol=atol)`` for the few joints of a stage, in plain
    Python: it runs at a demand instant, where numpy's per-call overhead was most of it."""
    x, y = a.tolist(), b.tolist()
    return len(x) == len(y) and all(abs(u - v) <= atol for u, v in zip(x, y, strict=True))


class SimulatedCamera:
    """Renders frames of the object for one camera on its (possibly moving) mount."""

    def __init__(
        self,
        camera: CameraModel,
        mount: CameraMount | Transform,
        geometry: ObjectGeometry | None = None,
        noise: SensorNoise | None = None,
        seed: int = 0,
        scene_of: Callable[[NDArray[np.float64]], Scene] | None = None,
        obstacles: Sequence[Obstacle] = (),
        optics: Optics | None = None,
    ) -> None:
        """``scene_of(state)``: the scene of a state 9-vector (default: the object's markers,
        :func:`object_scene`; commissioning: the boards on the carriage); ``obstacles``: the
        cell's solids, drawn in every frame; ``optics``: the lens and the exposure (depth of
        field, motion streak, exposure, response: :mod:`activesurv_sim.optics`; None: a
        pinhole's frames)."""
        self.camera = camera
        self.optics = optics
        self.scene_of = scene_of
        self.extra = obstacle_plates(obstacles)
        self.renderer = Renderer(camera)
        self.mount = mount
        self.geometry = ObjectGeometry() if geometry is None else geometry
        self.noise = SensorNoise() if noise is None else noise
        self.rng = np.random.default_rng(seed)
        self.objects = TimeSeries(9)  # the object (slot 0)
        self.slots: dict[int, TimeSeries] = {0: self.objects}  # several at once: one per lane
        n_joints = len(mount.joint_names) if isinstance(mount, CameraMount) else 0
        self.joints = TimeSeries(max(n_joints, 1))
        self._planned: dict[float, tuple[dict[int, NDArray[np.float64]], list[Any]]] = {}
        self._ahead: dict[
            float, tuple[NDArray[np.uint8], NDArray[np.float64], NDArray[np.float64]]
        ] = {}
        self._released: dict[float, NDArray[np.float64]] = {}  # the planned state it showed

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.mount.joint_names if isinstance(self.mount, CameraMount) else ()

    def camera_pose(self, t: float, hold: float = 0.2) -> Transform:
        """The camera pose at ``t``.

        Raises:
            RenderError: if the stage state at ``t`` is unknown.
        """
        if not isinstance(self.mount, CameraMount):
            return self.mount
        q = self.joints.at(t, hold)
        if q is None:
            raise RenderError(f'no stage state near t={t:.3f} s')
        return self.mount.pose_from_joints(q)

    def add_object(self, t: float, state: ArrayLike, slot: int = 0) -> bool:
        """An object state (9,) at ``t`` in lane ``slot``; False (ignored) if not finite."""
        series = self.slots.get(slot)
        if series is None:
            series = self.slots[slot] = TimeSeries(9)
        return series.add(t, state)

    def covered(self, t: float) -> bool:
        """Object and stage states are known at or after ``t`` (interpolation, no holding)."""
        latest = [series.latest_time for series in self.slots.values()]
        if self.joint_names:
            latest.append(self.joints.latest_time)
        return all(x is not None and x >= t for x in latest)

    def due(self, pending: Iterable[float], now: float, delay: float, hold: float) -> list[float]:
        """Requested instants whose frames are due at ``now``, in time order.

        A frame is due once the states around its instant have arrived (states at or after
        it prove the instant has passed, whatever the local clock says yet), and not before
        ``delay`` after it: a loaded machine delays a frame but never renders a stale pose.
        After ``delay + hold`` it is due anyway (rendered with the nearest states, or not at
        all).
        """
        return sorted(
            t
            for t in pending
            if (self.covered(t) and (delay <= 0.0 or now >= t + delay)) or now >= t + delay + hold
        )

    def warm_up(self) -> None:
        """Render one frame (a marker 0.5 m ahead) now: the first real frame then pays no lazy
        set-up (the noise pools are drawn here)."""
        marker = Plate.disc([0.0, 0.0, 0.5], [0.0, 0.0, -1.0], 0.0125, 0.03)
        self.renderer.render(
            Transform(np.eye(3), np.zeros(3)), Scene((marker,)), self.noise, self.rng
        )

    def plan(
        self,
        t: float,
        state: ArrayLike | None = None,
        q: ArrayLike | None = None,
        slot: int = 0,
        velocity: ArrayLike | None = None,
        q_rate: ArrayLike | None = None,
    ) -> None:
        """The object state (9,) of lane ``slot`` and/or stage joints planned for ``t``, with
        the object's velocity (m/s) and the joints' rates if known (the exposure's streak)."""
        states, joints = self._planned.setdefault(t, ({}, [None, None, None]))
        if state is not None:
            states[slot] = np.asarray(state, dtype=np.float64).reshape(9)
            if slot not in self.slots:
                # A lane planned before any state of it came (a camera hearing the states
                # around its instants only): known from now on, and the frames rendered ahead
                # without it are rendered again (the table plans every lane of an instant).
                self.slots[slot] = TimeSeries(9)
                self._ahead.clear()
            if slot == 0 and velocity is not None:
                joints[1] = np.asarray(velocity, dtype=np.float64).reshape(3)
        if q is not None:
            joints[0] = np.asarray(q, dtype=np.float64).reshape(-1)
            if q_rate is not None:
                joints[2] = np.asarray(q_rate, dtype=np.float64).reshape(-1)
        if len(self._planned) > 64:  # requests whose instant never came: keep the newest
            for old in sorted(self._planned)[:-64]:
                del self._planned[old]

    def render_ahead(self, t: float) -> bool:
        """Render the frame of ``t`` now if its truth is planned; True if a frame is ready."""
        if t in self._ahead:
            return True
        states, joints = self._planned.get(t, ({}, [None, None, None]))
        q, velocity, q_rate = joints
        static = not isinstance(self.mount, CameraMount)
        if set(states) != set(self.slots) or (q is None and not static):
            return False
        state = np.concatenate([states[k] for k in sorted(self.slots)])
        q_used = np.zeros(0) if static or q is None else q
        rates = None
        if velocity is not None:
            rate = np.zeros_like(state)
            rate[0:3] = rate[3:6] = velocity  # the carriage carries both markers
            q_dot = np.zeros_like(q_used) if q_rate is None or static else q_rate
            rates = (rate, q_dot)
        self._ahead[t] = (self.render_state(state, q_used, rates), state, q_used)
        return True

    def ahead_frame(self, t: float) -> NDArray[np.uint8] | None:
        """The frame of ``t`` rendered ahead and not yet released, or None."""
        ahead = self._ahead.get(t)
        return None if ahead is None else ahead[0]

    def release(self, t: float) -> NDArray[np.uint8] | None:
        """The frame of ``t`` rendered ahead, taken at the instant on the camera's own trigger,
        or None (it then waits for the states of ``t``: :meth:`frame_at`).

        Taken only if the stage's state stamped ``t`` (the commanded profile's, known ahead
        and replaced by every new goal) is the one it was rendered with. The object's is its
        planned state, the simulated table's path being fixed ahead;
        :meth:`released_differs` checks it when the table's state of ``t`` arrives.
        """
        ahead = self._ahead.get(t)
        if ahead is None:
            return None
        frame, state, q = ahead
        if self.joint_names:
            now = self.joints.at(t) if self.joints.has(t) else None
            if now is None or not _same(now, q):
                return None
        del self._ahead[t]
        self._planned.pop(t, None)
        self._released[t] = state
        if len(self._released) > RELEASED_KEPT:  # instants whose table state never came
            for old in sorted(self._released)[:-RELEASED_KEPT]:
                del self._released[old]
        return frame

    def released_differs(self, t: float) -> bool:
        """Whether the frame released at ``t`` showed an object state other than the table's
        own state of ``t``, once every lane's has arrived (checked once; False until then)."""
        if t not in self._released or not all(s.has(t) for s in self.slots.values()):
            return False
        shown = self._released.pop(t)
        parts = [self.slots[k].at(t) for k in sorted(self.slots)]
        truth = np.concatenate([p for p in parts if p is not None])
        return shown.shape != truth.shape or not np.allclose(shown, truth, rtol=0.0, atol=1e-6)

    def frame_at(self, t: float, hold: float = 0.2) -> tuple[NDArray[np.uint8], bool]:
        """The frame exposed at ``t``, and whether it was rendered ahead.

        Raises:
            RenderError: if the object or stage state at ``t`` is unknown.
        """
        state, q = self.truth_at(t, hold)
        self._planned.pop(t, None)
        ahead = self._ahead.pop(t, None)
        for old in [k for k in self._ahead if k < t]:
            del self._ahead[old]  # frames of instants that passed without a request
        if ahead is not None:
            frame, s0, q0 = ahead
            if np.allclose(s0, state, rtol=0.0, atol=1e-6) and np.allclose(
                q0, q, rtol=0.0, atol=1e-6
            ):
                return frame, True
        return self.render_state(state, q, self.rates_at(t, hold)), False

    def rates_at(
        self, t: float, hold: float = 0.2
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The state's and the joints' rates of change around ``t`` over the exposure (from the
        states on either side; None without optics or without them)."""
        if self.optics is None:
            return None
        h = self.optics.exposure_time / 2.0
        try:
            a, qa = self.truth_at(t - h, hold)
            b, qb = self.truth_at(t + h, hold)
        except RenderError:
            return None
        if a.shape != b.shape or qa.shape != qb.shape:
            return None
        return (b - a) / (2.0 * h), (qb - qa) / (2.0 * h)

    def frame_optics(
        self,
        plates: Sequence[Plate],
        q: NDArray[np.float64],
        rates: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    ) -> FrameOptics:
        """What the lens and the shutter do to a frame of ``plates`` (the object's or the
        boards, obstacles apart) with the stage at joints ``q``: the depth of field's blur at
        the distance of the plate the camera looks at (the nearest to its optical axis) and
        that plate's streak over the exposure (the carriage's rate, ``rates[0][:3]``, and the
        joints', ``rates[1]``)."""
        T = self._pose(q)
        if self.optics is None or not plates:
            return frame_optics(self.camera, None, T, T.t)
        axis = T.R[:, 2]

        def off_axis(plate: Plate) -> float:
            d = plate.center - T.t
            return float(-(d @ axis) / (np.linalg.norm(d) + 1e-12))

        p = min(plates, key=off_axis).center
        ends = None
        if rates is not None:
            h = self.optics.exposure_time / 2.0
            v = rates[0][0:3]
            q_dot = rates[1] if len(q) else np.zeros_like(q)
            ends = (
                (self._pose(q - h * q_dot), p - h * v),
                (self._pose(q + h * q_dot), p + h * v),
            )
        return frame_optics(self.camera, self.optics, T, p, ends)

    def _pose(self, q: NDArray[np.float64]) -> Transform:
        if isinstance(self.mount, CameraMount):
            return self.mount.pose_from_joints(np.asarray(q, dtype=np.float64))
        return self.mount

    def truth_at(
        self, t: float, hold: float = 0.2
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Object state (9,) and stage joints at ``t`` (joints empty for a static mount).

        Raises:
            RenderError: if the object or stage state at ``t`` is unknown.
        """
        # The table keeps moving while its states are late: past the newest state the object is
        # extrapolated along its last motion (a loaded machine delays a state, it does not stop
        # the object); the stages' joints are held (a stage at rest is where it was).
        state = self.objects.at(t, hold, extrapolate=True, max_rate=TABLE_MAX_RATE)
        if state is None:
            raise RenderError(f'no object state near t={t:.3f} s')
        if len(self.slots) > 1:  # several objects: every lane's (an unknown one is empty)
            parts = [state]
            for k in sorted(self.slots)[1:]:
                other = self.slots[k].at(t, hold, True, TABLE_MAX_RATE)
                parts.append(EMPTY_LANE if other is None else other)
            state = np.concatenate(parts)
        if not isinstance(self.mount, CameraMount):
            return state, np.zeros(0)
        q = self.joints.at(t, hold)
        if q is None:
            raise RenderError(f'no stage state near t={t:.3f} s')
        return state, q

    def render_state(
        self,
        state: ArrayLike,
        q: ArrayLike,
        rates: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    ) -> NDArray[np.uint8]:
        """The frame of the object in ``state`` (9,) with the stage at joints ``q``; ``rates``
        (of the state and the joints) streak it over the exposure."""
        q = np.asarray(q, dtype=np.float64)
        T = self._pose(q)
        s = np.asarray(state, dtype=np.float64)
        if self.scene_of is None:
            objects = s.reshape(-1, 9)
            plates = [p for o in objects for p in object_scene(o, self.geometry).plates]
            scene = Scene((*plates, *self.extra))
            seen = plates
        else:
            scene = self.scene_of(s)
            seen = list(scene.plates)
            scene = replace(scene, plates=scene.plates + self.extra)
        optics = self.frame_optics(seen, q, rates)
        return self.renderer.render(T, scene, self.noise, self.rng, optics)

    def render_at(self, t: float, hold: float = 0.2) -> NDArray[np.uint8]:
        """The frame exposed at ``t`` (rendered now).

        Raises:
            RenderError: if the object or stage state at ``t`` is unknown.
        """
        return self.render_state(*self.truth_at(t, hold), self.rates_at(t, hold))


OBJECT_GONE = 2.0  # s without an object state: the lab's table shows the calibration boards


def on_table(objects: SimulatedCamera, boards: SimulatedCamera, t: float) -> SimulatedCamera:
    """What a lab camera sees on the table at ``t``: the object (``objects``) while its states
    come, within :data:`OBJECT_GONE` of ``t`` by their stamps, else the calibration boards."""
    last = objects.objects.latest_time
    return objects if last is not None and last > t - OBJECT_GONE else boards
