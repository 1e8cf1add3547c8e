"""The orchestrator's one ROS node: which nodes are up, stages moved and waited for, captures.

Every route that holds a graph (experiments, sessions, hardware runs, commissioning, delay
measurement, replay) talks to it through one :class:`Observer`, on the topics and QoS of
:mod:`activesurv_common.ros.topics` and :mod:`activesurv_common.ros.qos`::

    with Observer('commissioner', namespace) as obs:      # rclpy started here if it is not
        obs.watch_stages(['cam1', 'xy_table'])
        with GraphSession(runner, specs, obs.missing_stages, obs.spin):
            obs.move('cam1', ['cam1_x', 'cam1_yaw'], q)   # goal sent, waits until there at rest
            gray = obs.capture('cam1', ('cam1', 'xy_table'))

A run's monitor (:class:`activesurv_bringup.experiments.graph.RunMonitor`) is an Observer that
also watches the clock, the estimates and the recorder. Only the CLI's subcommands load this
module (lazily): the report and evaluation tools never start a ROS client.
"""

from __future__ import annotations

import contextlib
import time
from collections import deque
from collections.abc import Callable, Collection, Iterable, Sequence
from types import TracebackType
from typing import Any, Self

import numpy as np
import rclpy
from numpy.typing import NDArray
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_srvs.srv import Trigger

from activesurv_bringup.errors import NodeDiedError
from activesurv_common.camera_model import CameraModel
from activesurv_common.ros import qos, topics
from activesurv_common.ros.conversions import image_to_gray, model_from_camera_info, sec_to_time
from activesurv_common.ros.node import make_executor
from activesurv_interfaces.msg import CaptureRequest, StageGoal
from activesurv_recording.bagio import cdr_header

FRAMES_KEPT = 60  # per camera: two seconds of a 30 Hz driver
Positions = Sequence[float] | NDArray[np.float64]  # m or rad, per joint
CAPTURE_LEAD = 0.15  # s from a capture request to its instant (the camera's notice)
# s a capture waits for its frame, and how many requests it makes: commissioning on a slow host
# beside other work (clean-clone test suites on a 1.6x slower host) saw a first request bring
# no frame in 5 s, and in 15 s.
CAPTURE_TIMEOUT = 10.0
CAPTURE_ATTEMPTS = 2
DRAIN_WAIT = 0.002  # s: spin_batched's last round, that finds nothing waiting
DRAIN_ROUNDS = 10_000  # what one batch handles at most (the rest waits for the next)


class Observer:
    """The orchestrator's own node (a context manager: rclpy is started on entry if nothing
    in this process has, and shut on exit then; the node is destroyed on exit).

    Args:
        name: the node's name.
        namespace: the rig's namespace ('' for a simulated run).
    """

    def __init__(self, name: str, namespace: str = '') -> None:
        self.name = name
        self.namespace = namespace
        self._owns_rclpy = False
        self._node: Node | None = None
        self._executor: Executor | None = None
        self._stage_subs: list[Any] = []  # watch_stages' subscriptions
        self.states: dict[str, JointState] = {}
        self._goal_pubs: dict[str, Any] = {}
        self.frames: dict[str, deque[tuple[float, bytes]]] = {}
        self.infos: dict[str, CameraInfo] = {}
        self._capture_pub: Any = None
        self._triggers: dict[str, Any] = {}  # camera -> its std_srvs/Trigger client
        self._calls: deque[Any] = deque(maxlen=256)  # trigger calls in flight
        self._paced: dict[str, tuple[float, float]] = {}  # camera -> (period, next call)
        self.requests = 0
        self.settle_timeout = 20.0  # s for a stage to reach a goal (move)

    def __enter__(self) -> Self:
        if not rclpy.ok():
            # SIGINT stays Python's (KeyboardInterrupt, or a session's own handler): the nodes
            # are stopped in order by the GraphSession rather than this context shut under it.
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
            self._owns_rclpy = True
        self._node = rclpy.create_node(self.name, namespace=self.namespace or None)
        # One executor for the node's life: rclpy.spin_once(node) adds the node to the global
        # executor and removes it again at every call. (What cost a lab session's monitor a
        # sixth of a core was hearing every goal and poll: see unwatch_stages.) The nodes'
        # executor (rclpy's EventsExecutor): a run's monitor took 0.13 s of CPU against 0.35 s
        # on the single-threaded one (Set A fast, four runs each).
        self._executor = make_executor()
        self._executor.add_node(self._node)
        self.on_start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def on_start(self) -> None:
        """Subscriptions a subclass makes once its node exists."""

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=0.0)
            self._executor = None
        if self._node is not None:
            self._node.destroy_node()
            self._node = None
        if self._owns_rclpy:
            rclpy.try_shutdown()
            self._owns_rclpy = False

    @property
    def node(self) -> Node:
        if self._node is None:
            raise RuntimeError(f'{self.name}: used outside its "with" block')
        return self._node

    # -- time and spinning ---------------------------------------------------------------

    def now(self) -> float:
        """This node's clock (s)."""
        return float(self.node.get_clock().now().nanoseconds) * 1e-9

    def _spin_once(self, timeout: float) -> None:
        if self._executor is None:
            raise RuntimeError(f'{self.name}: used outside its "with" block')
        self._executor.spin_once(timeout_sec=timeout)

    def spin(self, seconds: float) -> None:
        """Handle what comes for ``seconds``."""
        end = time.monotonic() + seconds
        while True:
            left = end - time.monotonic()
            if left <= 0.0:
                return
            self._spin_once(min(0.01 if self._paced else 0.05, left))
            self._pace()
            self.on_spin()

    def spin_batched(self, seconds: float) -> None:
        """Sleep ``seconds``, then handle what came meanwhile, all at once.

        For a watcher that need not react at once (a run's monitor while the graph runs): it
        wakes once a period instead of at every message, so at a demand instant, when every
        camera publishes its observation, its callbacks do not take a core from the imagers and
        fusion. A monitor that paces triggers spins as usual."""
        if self._paced:
            self.spin(seconds)
            return
        time.sleep(seconds)
        # Each round handles one waiting event; one that finds none waits out its timeout.
        for _ in range(DRAIN_ROUNDS):
            started = time.monotonic()
            self._spin_once(DRAIN_WAIT)
            if time.monotonic() - started >= 0.9 * DRAIN_WAIT:
                break
        self.on_spin()

    def on_spin(self) -> None:
        """Called after every callback round (a wall-clock run's time is kept here)."""

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        """Spin until ``done()`` (True) or ``timeout`` seconds pass (False)."""
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                return False
            self._spin_once(0.01 if self._paced else 0.02)
            self._pace()
            self.on_spin()
        return True

    def missing(self, expected: Collection[str]) -> set[str]:
        """The named nodes not (yet) in the graph."""
        present = {n for n, _ in self.node.get_node_names_and_namespaces()}
        return set(expected) - present

    # -- stages --------------------------------------------------------------------------

    def watch_stages(
        self, stages: Iterable[str], on_state: Callable[[str, JointState], None] | None = None
    ) -> None:
        """Publish goals to and hear the joint states of ``stages`` (``on_state`` per state)."""
        for stage in stages:
            if stage in self._goal_pubs:
                continue
            self._goal_pubs[stage] = self.node.create_publisher(
                StageGoal, topics.goal(stage), qos.GOAL
            )

            def keep(msg: JointState, stage: str = stage) -> None:
                self.states[stage] = msg
                if on_state is not None:
                    on_state(stage, msg)

            self._stage_subs.append(
                self.node.create_subscription(
                    JointState, topics.joint_states(stage), keep, qos.STATE
                )
            )

    def unwatch_stages(self) -> None:
        """Stop hearing the stages' joint states (``states`` keeps the last of each): a running
        graph's monitor need not wake for every poll of every controller."""
        for sub in self._stage_subs:
            self.node.destroy_subscription(sub)
        self._stage_subs.clear()

    def missing_stages(self) -> set[str]:
        """The watched stages not heard from yet (a GraphSession's ``missing``)."""
        return {f'{s} (no joint states)' for s in self._goal_pubs if s not in self.states}

    def send_goal(
        self,
        stage: str,
        names: Sequence[str],
        q: Positions,
        velocities: Sequence[float] | None = None,
    ) -> None:
        """Publish a goal (joint names, positions in m or rad; 0 velocity: the stage's own)."""
        msg = StageGoal()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.joint_names = list(names)
        msg.positions = [float(v) for v in q]
        msg.max_velocities = [float(v) for v in velocities or [0.0] * len(names)]
        self._goal_pubs[stage].publish(msg)

    def at(self, stage: str, names: Sequence[str], q: Positions, tol: float) -> bool:
        """The stage reports ``q`` (within ``tol``) and stands still."""
        msg = self.states.get(stage)
        if msg is None:
            return False
        table = dict(zip(msg.name, msg.position, strict=False))
        speed = dict(zip(msg.name, msg.velocity, strict=False))
        return all(
            n in table and abs(table[n] - v) <= tol and abs(speed.get(n, 0.0)) < 1e-9
            for n, v in zip(names, q, strict=True)
        )

    def move(
        self,
        stage: str,
        names: Sequence[str],
        q: Positions,
        tol: float = 1e-5,
        velocities: Sequence[float] | None = None,
        timeout: float | None = None,
    ) -> None:
        """Send a goal and wait until the stage reports it there (within ``tol``, m or rad: a
        controller rounds to its steps), at rest; captures use the positions reported then.

        Raises:
            NodeDiedError: if it does not get there in ``timeout`` seconds (default
                :attr:`settle_timeout`).
        """
        if self.at(stage, names, q, tol):
            return
        self.send_goal(stage, names, q, velocities)
        timeout = self.settle_timeout if timeout is None else timeout
        if not self.spin_until(lambda: self.at(stage, names, q, tol), timeout):
            raise NodeDiedError(
                f'{stage} did not reach {np.round(np.asarray(q), 5).tolist()} in {timeout:.0f} s'
            )

    # -- cameras -------------------------------------------------------------------------

    def watch_camera(
        self, camera_id: str, image_topic: str, info_topic: str, trigger_service: str = ''
    ) -> None:
        """Keep the newest frames (serialized, stamped) and the camera_info of a camera;
        ``trigger_service``: a software-triggered camera's ``std_srvs/Trigger`` (it sends a
        frame only when called: :meth:`trigger`)."""
        frames: deque[tuple[float, bytes]] = deque(maxlen=FRAMES_KEPT)
        self.frames[camera_id] = frames
        self._capture_publisher()  # made now: matched to the cameras by the first capture
        if trigger_service:
            self._triggers[camera_id] = self.node.create_client(Trigger, trigger_service)

        def keep(data: bytes) -> None:
            with contextlib.suppress(ValueError):  # not an Image: skipped
                frames.append((cdr_header(data)[0], data))

        def keep_info(msg: CameraInfo) -> None:
            self.infos[camera_id] = msg

        # Best effort, as camera drivers publish (a reliable subscription would never match).
        self.node.create_subscription(Image, image_topic, keep, qos.SENSOR, raw=True)
        self.node.create_subscription(CameraInfo, info_topic, keep_info, qos.SENSOR)

    def capture(
        self, camera_id: str, latched: Sequence[str], timeout: float = CAPTURE_TIMEOUT
    ) -> NDArray[np.uint8]:
        """Trigger ``camera_id`` (and latch the ``latched`` stages) a moment from now; its
        frame, grey.

        A request that brings no frame is made once more, for a new instant (a slow host's
        first request of a session was seen to bring none), before the camera is given up.

        Raises:
            NodeDiedError: if neither request brings a frame stamped at or after its instant
                in ``timeout``.
        """
        pub = self._capture_publisher()
        # A request published before the camera's reader matched is lost (volatile): the
        # first capture of a session on a slow host otherwise waited out its timeout.
        if not self.spin_until(lambda: pub.get_subscription_count() > 0, timeout):
            raise NodeDiedError(f'nothing subscribes to {topics.CAPTURE_REQUEST} ({camera_id})')
        for _attempt in range(CAPTURE_ATTEMPTS - 1):
            with contextlib.suppress(NodeDiedError):
                return self._capture_once(pub, camera_id, latched, timeout)
        return self._capture_once(pub, camera_id, latched, timeout)

    def _capture_once(
        self, pub: Any, camera_id: str, latched: Sequence[str], timeout: float
    ) -> NDArray[np.uint8]:
        t = self.now() + CAPTURE_LEAD
        msg = CaptureRequest()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.demand_index = self.requests
        self.requests += 1
        msg.demand_instant = sec_to_time(t)
        msg.camera_ids = [camera_id, *latched]
        frames = self.frames[camera_id]
        frames.clear()
        pub.publish(msg)
        if camera_id in self._triggers:  # it exposes when called: at the instant
            self.spin_until(lambda: self.now() >= t, CAPTURE_LEAD + 1.0)
            self.trigger(camera_id)

        def arrived() -> bool:
            return any(s >= t - 1e-6 for s, _ in frames)

        if not self.spin_until(arrived, timeout):
            raise NodeDiedError(
                f'{camera_id} sent no frame for a capture request in {timeout:.0f} s'
            )
        data = next(d for s, d in frames if s >= t - 1e-6)
        return np.asarray(image_to_gray(deserialize_message(data, Image)), dtype=np.uint8)

    def _capture_publisher(self) -> Any:
        if self._capture_pub is None:
            self._capture_pub = self.node.create_publisher(
                CaptureRequest, topics.CAPTURE_REQUEST, qos.EVENTS
            )
        return self._capture_pub

    def triggered(self, camera_id: str) -> bool:
        """Whether the camera sends frames only when :meth:`trigger` calls it."""
        return camera_id in self._triggers

    def trigger(self, camera_id: str) -> None:
        """Call a software-triggered camera's service (not waited for: it exposes as called).

        Raises:
            NodeDiedError: if the service is not offered.
        """
        client = self._triggers[camera_id]
        if not client.service_is_ready() and not client.wait_for_service(timeout_sec=2.0):
            raise NodeDiedError(f'{camera_id}: no trigger service {client.srv_name}')
        self._calls.append(client.call_async(Trigger.Request()))
        while self._calls and self._calls[0].done():
            self._calls.popleft()

    def pace(self, camera_id: str, rate: float | None) -> None:
        """Trigger a software-triggered camera at ``rate`` Hz while this observer spins (a
        stream of frames, as a free-running camera sends); ``None``: stop. A camera that is
        not software-triggered is left alone."""
        self._paced.pop(camera_id, None)
        if rate and camera_id in self._triggers:
            self._paced[camera_id] = (1.0 / rate, time.monotonic())

    def _pace(self) -> None:
        now = time.monotonic()
        for cid, (period, due) in list(self._paced.items()):
            if now >= due:
                self.trigger(cid)
                self._paced[cid] = (period, max(due + period, now - period))

    def camera_model(
        self, camera_id: str, fallback: CameraModel, timeout: float = 2.0
    ) -> CameraModel:
        """What the camera's driver says of its optics (camera_info), else ``fallback``."""
        self.spin_until(lambda: camera_id in self.infos, timeout)
        if camera_id not in self.infos:
            return fallback
        return model_from_camera_info(self.infos[camera_id], camera_id)
