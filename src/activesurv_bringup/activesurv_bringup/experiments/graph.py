"""Graph mode: one experiment run as the real node graph over DDS, recorded to a bag.

Like a launch file, :func:`graph_specs` lists every node with its parameters; :func:`run_graph`
starts them as processes, the recorder first; the simulated xy table (which owns ``/clock``)
starts with them but holds simulated time at 0 until released once every node has joined the
graph (a table that cannot be held starts last then), so simulated time starts only when
nothing can miss the object entering. A monitor node in this process shows progress (demand
j of m, simulated time) and ends the run when every demand has an answer or time runs out. The
nodes are then stopped in reverse order, the recorder last.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from collections.abc import Callable, Collection, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Empty, Float64MultiArray, String

from activesurv_bringup.errors import ConfigError, NodeDiedError
from activesurv_bringup.experiments.experiment import Experiment
from activesurv_bringup.experiments.faults import Fault, FaultKind, Kill
from activesurv_bringup.experiments.options import RunOptions, scoped_environ
from activesurv_bringup.observer import Observer
from activesurv_bringup.specs import imager_spec, mount_parameters, stage_spec
from activesurv_common.calibration import pose_to_list
from activesurv_common.ros import callback_cpu, qos, topics
from activesurv_dispatch.sensors import Sensor, setup_to_dict
from activesurv_interfaces.msg import CaptureRequest, TargetEstimate
from activesurv_launch.launcher import Launcher, NodeSpec, container
from activesurv_launch.netns import NetnsHosts
from activesurv_launch.ros.compose import Composition
from activesurv_launch.runner import NodeRunner
from activesurv_launch.session import GraphSession
from activesurv_recording.run_record import RunRecord
from activesurv_sim.rig import save_rig

Progress = Callable[[str], None]


def rig_files(exp: Experiment, out: Path) -> dict[str, str]:
    """Write the run's rig (the simulator's truth), its calibration and the believed set-up
    into ``out/rig`` for the nodes; returns the paths (empty without a rig)."""
    if exp.rig is None:
        return {}
    d = out / 'rig'
    d.mkdir(parents=True, exist_ok=True)
    save_rig(exp.rig.rig, d / 'rig.yaml')
    exp.rig.calibration.save(d / 'calibration')
    (d / 'setup.yaml').write_text(yaml.safe_dump(setup_to_dict(exp.setup), sort_keys=False))
    return {
        'rig_file': str(d / 'rig.yaml'),
        'calibration': str(d / 'calibration'),
        'setup_file': str(d / 'setup.yaml'),
    }


CLOCK_STATES = 4
"""A graph run's table ticks ``/clock`` on every this many object states (``clock_period``)."""


def graph_specs(
    exp: Experiment,
    bag: Path,
    rtf: float = 1.0,
    image_rate: float = 2.0,
    faults: Sequence[Fault] = (),
    thin: Sequence[str] = (),
    split_hosts: bool = False,
    preview_rate: float = 0.0,
    record: RunRecord | None = None,
) -> list[NodeSpec]:
    """Every node of the run with its parameters, in start order (xy table last).

    ``record``: the run record the recorder stores (default: the experiment's with ``faults``).

    ``thin`` adds topics the recorder thins to ``image_rate``; with ``split_hosts`` each
    camera's nodes go on host ``camN`` and the rest on ``core``; ``preview_rate`` (Hz) makes
    the dynamic cameras stream previews for viewers (never recorded).
    """
    sim = {'use_sim_time': True}
    files = rig_files(exp, bag.parent)
    over = pose_to_list(exp.overhead(truth=False)[1])  # as the system believes it
    truth = {'rig_file': files['rig_file']} if files else {}
    believed = {'setup_file': files['setup_file']} if files else {}

    by_cam = {f.camera: f for f in faults}
    specs = [
        NodeSpec(
            'recorder',
            'activesurv_recording.recorder_node',
            nice=RECORDER_NICE,
            parameters={
                **sim,
                'output': str(bag),
                'image_rate': float(image_rate),
                'run_info': (record or exp.record(faults)).to_json(),
                'thin_topics': ['/overhead/image_raw', '/overhead/camera_info', *thin],
                'exclude': ['/rosout', '/parameter_events']
                + [
                    f'/{c}/preview/image_raw'
                    for c in ['overhead', *(s.camera_id for s in exp.setup.sensors)]
                ],
            },
        ),
        NodeSpec(
            'overhead_camera',
            'activesurv_sim.sim_camera_node',
            parameters={
                **sim,
                'camera_id': 'overhead',
                'camera_type': 'overhead',
                'mount.static_pose': over,
                **truth,
                **_intrinsics(files, 'overhead'),
                'frame_rate': exp.overhead_rate,
                # Half a frame period off the grid the demand instants lie on: the overhead
                # frame, its fix, prediction and plan never fall on an instant's imaging, and
                # every run takes the same frames (lockstep takes them on the grid itself).
                'frame_phase': 0.5 / exp.overhead_rate,
                'seed': exp.seed * 100 + 99,
            },
        ),
        # Simulated time starts once its fixes reach the predictor and the recorder.
        locator_spec(exp, {**sim, 'wait_for_readers': 2}, over, exp.setup.marker_radius),
        *core_specs(exp, sim, believed, over, exp.demand_times, bag.parent / 'logs'),
    ]
    for i, sensor in enumerate(exp.setup.sensors):
        specs += camera_specs(exp, i, sensor, by_cam.get(sensor.camera_id), files, preview_rate)
    if split_hosts:
        specs = [
            replace(s, host=s.name.split('_')[0] if s.name.startswith('cam') else 'core')
            for s in specs
        ]
    table = _table_parameters(exp, rtf, preview_rate, truth, specs)
    host = 'core' if split_hosts else ''
    specs.append(NodeSpec('xy_table', 'activesurv_sim.xy_table_node', parameters=table, host=host))
    return specs


def _table_parameters(
    exp: Experiment,
    rtf: float,
    preview_rate: float,
    truth: dict[str, str],
    specs: Sequence[NodeSpec],
) -> dict[str, Any]:
    """The simulated xy table's parameters in a graph run (``specs``: the other nodes)."""
    cams = [s for s in specs if s.module.endswith('sim_camera_node')]
    return {
        **exp.table_config().to_parameters(),
        # /clock and object states at the overhead camera's rate and on its frames (half a
        # period off the instants' grid): every demand instant gets a tick and a state of its
        # own, and each tick wakes every process (at 20 Hz a run took 0.04 cores more;
        # docs/performance.md). Previews for a live view are paced by the states: twice the
        # rate then, on the same grid, so they reach their 12 Hz.
        'publish_rate': exp.overhead_rate * (2.0 if preview_rate > 0.0 else 1.0),
        'publish_phase': 0.5 / exp.overhead_rate,
        'publish_clock': True,
        # An instant gets its state (the cameras image on it) but no tick: a tick wakes all
        # nine processes just when three cameras image on two cores (alternating runs, Set A
        # fast: median latency 16.0 against 18.4 ms; docs/performance.md). Stamps between
        # ticks are read off the extrapolated clock (FineClock, the recorder's ClockEstimate).
        'instant_ticks': False,
        # Nothing of the system reads the instant's state (the truth): it goes out once the
        # cameras have imaged, not while (alternating runs, Set A fast: median latency 13.7
        # against 15.3 ms; docs/performance.md). Before the grid's next state in any case.
        'instant_state_delay': 0.025,
        # A /clock tick on every fourth state (each wakes every process and every timer of
        # simulated time: Set A fast, ten alternating pairs against every other state, 0.397
        # -> 0.344 cores, median latency 11.7 -> 11.0 ms; docs/performance.md); what keeps its
        # rate runs on the table's grid (``instants.periodic``; docs/node-graph.md).
        'clock_period': CLOCK_STATES / exp.overhead_rate,
        'real_time_factor': float(rtf),
        **truth,
        # The recorder and every simulated camera must hear the object from the start: on
        # every state, or (imaging on requests) on those around the instants.
        'wait_for_subscribers': 1 + sum(1 for s in cams if not s.parameters.get('instant_states')),
        'wait_for_instant_subscribers': sum(1 for s in cams if s.parameters.get('instant_states')),
    }


def _intrinsics(files: dict[str, str], camera_id: str) -> dict[str, str]:
    """A simulated camera's published intrinsics: its commissioned calibration, if any."""
    return {'camera_info_file': f'{files["calibration"]}/{camera_id}.yaml'} if files else {}


def camera_specs(
    exp: Experiment,
    i: int,
    s: Sensor,
    fault: Fault | None,
    files: dict[str, str],
    preview_rate: float,
) -> list[NodeSpec]:
    """One dynamic camera's simulated stage, simulated camera and imager (none if ``fault``
    says it is dead)."""
    sim = {'use_sim_time': True}
    truth = {'rig_file': files['rig_file']} if files else {}
    cid = s.camera_id
    if fault is not None and fault.kind is FaultKind.DEAD:
        return []  # the camera's nodes are not running
    stage = stage_spec(s, exp.setup.initial[cid], exp.system, 10.0, sim_time=True)
    cam_params: dict[str, Any] = {
        **sim,
        'camera_id': cid,
        'frame_rate': 0.0,
        'preview_rate': float(preview_rate),
        # Imaging on requests, it needs the object's states around its instants only, not
        # every state (3 % of a run's CPU; docs/performance.md); previews need them all.
        'instant_states': preview_rate <= 0.0,
        'seed': exp.seed * 100 + i,
        **mount_parameters(s),
        **truth,
        **_intrinsics(files, cid),
    }
    imager = imager_spec(
        s,
        exp.imager_config(cid, fault).to_parameters(),
        sim_time=True,
        extra={
            'reliable_images': True,
            **({'obstacles_file': files['setup_file']} if exp.setup.obstacles else {}),
        },
    )
    if fault is not None and fault.kind is FaultKind.FROZEN:
        cam_params['inject_frozen'] = True
    return [
        stage,  # 10 Hz: states at the demand instants come extra
        NodeSpec(f'{cid}_camera', 'activesurv_sim.sim_camera_node', parameters=cam_params),
        imager,
    ]


def locator_spec(
    exp: Experiment,
    clock: dict[str, Any],
    over: list[float],
    marker_radius: float,
    remappings: dict[str, str] | None = None,
) -> NodeSpec:
    """The overhead locator: top-marker fixes from the overhead camera's frames."""
    return NodeSpec(
        'overhead_locator',
        'activesurv_imaging.overhead_locator_node',
        parameters={
            **clock,
            'camera_pose': over,
            'marker_height': exp.object_model.top_height,
            'marker_radius': marker_radius,
        },
        remappings=remappings or {},
    )


def core_specs(
    exp: Experiment,
    clock: dict[str, Any],
    believed: dict[str, str],
    over: list[float],
    demand_times: Sequence[float],
    logs: Path,
    capture_hold: float = 0.0,
) -> list[NodeSpec]:
    """Predictor, dispatcher, frames and fusion: the same in simulated and hardware runs but
    for their ``clock`` (``use_sim_time``), the believed set-up and the demand instants
    (``capture_hold``: a rig's free-running cameras, see :func:`capture_hold`)."""
    dispatcher = exp.dispatcher_config()
    return [
        NodeSpec(
            'predictor',
            'activesurv_prediction.predictor_node',
            parameters={**clock, **exp.predictor_config(demand_times).to_parameters()},
        ),
        NodeSpec(
            'dispatcher',
            'activesurv_dispatch.dispatcher_node',
            parameters={
                **clock,
                'motion_class': exp.system,
                **believed,
                'k': dispatcher.k,
                'rho': dispatcher.rho,
                'capture_lead': dispatcher.capture_lead,
                'settle_time': dispatcher.settle_time,
                'capture_hold': float(capture_hold),
            },
        ),
        NodeSpec(
            'frames',
            'activesurv_liveview.frames_node',
            parameters={**clock, 'motion_class': exp.system, 'overhead_pose': over, **believed},
        ),
        NodeSpec(
            'fusion',
            'activesurv_fusion.fusion_node',
            parameters={
                **clock,
                **exp.fusion_config().to_parameters(),
                'journal': str(logs / 'fusion.journal'),
                # Simulated time starts once it hears the clock, requests and observations: on
                # a loaded host its participant once matched them 2.5 s into the run, and the
                # first estimate was stamped at time 0.
                'announce_ready': True,
            },
        ),
    ]


CAMERA_MODULES = (
    'activesurv_sim.sim_camera_node',
    'activesurv_hardware.camera_node',  # a camera's driver: with its imager, on its host
    'activesurv_sim.sim_stage_node',
    'activesurv_imaging.imager_node',
    'activesurv_stages.stage_bridge_node',
)
ALONE_MODULES = (
    'activesurv_recording.recorder_node',
    'activesurv_sim.xy_table_node',
    'activesurv_fusion.fusion_node',
)
# Groups whose work is not on a demand's critical path (tracking, planning ahead): at a
# demand instant they yield the CPU to the cameras' imaging and to fusion.
BACKGROUND = {'core': 5, 'overhead': 5}
# The recorder writes what the others did: at a demand instant it wakes for every frame, stage
# state and observation, and its copies and writes queued before the imagers' work delayed the
# estimate by a fifth (Set A fast at rtf 1, six runs each alternately: median latency 23.1 ->
# 18.3 ms at nice 10, its messages all recorded: reliable, it only lags). Not in hardware runs:
# there the lab saturates the machine and the recorder's wall-clock receive time is the latency
# (a lab session at 15 Hz: median 96.5 ms at nice 0, 115.6 ms at nice 10).
RECORDER_NICE = 10


def group_processes(specs: Sequence[NodeSpec], alone: Sequence[str] = ()) -> list[NodeSpec]:
    """Node specs grouped into container processes, as a real rig would run them per host.

    Each dynamic camera's stage, camera and imager share a container ``camN`` (with
    ``--hosts netns`` that is the camera's host): its frames go to its imager inside the
    process, and the cameras render and measure in parallel on separate cores. The overhead
    camera and its locator share ``overhead``; predictor and dispatcher ``core``; both run
    at a lower CPU priority (:data:`BACKGROUND`: they plan ahead, and at a demand instant
    the imagers and fusion are what the estimate waits for). The recorder (its disk writes
    must not stall anyone), the xy table (it owns /clock and holds it), fusion (the last
    step of every demand, never queued behind a replan) and the nodes named in ``alone``
    (nodes to kill and restart, load generators) run as processes of their own. Start order
    is kept: a group starts where its first member stood.
    """
    groups: dict[str, list[NodeSpec]] = {}
    order: list[NodeSpec | str] = []
    for s in specs:
        if s.members or s.module in ALONE_MODULES or s.name in alone:
            order.append(s)
            continue
        key = s.name.split('_')[0] if s.module in CAMERA_MODULES else 'core'
        if s.module == 'activesurv_imaging.overhead_locator_node':
            key = 'overhead'  # with the overhead camera: its frames stay in the process
        if key not in groups:
            groups[key] = []
            order.append(key)
        groups[key].append(s)
    out: list[NodeSpec] = []
    for item in order:
        if isinstance(item, NodeSpec):
            out.append(item)
        elif len(groups[item]) == 1:
            out.append(groups[item][0])
        else:
            out.append(
                container(item, groups[item], groups[item][0].host, BACKGROUND.get(item, 0))
            )
    return out


class RunMonitor(Observer):
    """The orchestrator's node in a run: simulated time (or run time on a rig's wall clock),
    the estimates, and what the recorder holds of every per-demand event heard here."""

    def __init__(
        self, expected_nodes: Sequence[str], time_origin: float | None = None, namespace: str = ''
    ) -> None:
        super().__init__('activesurv_monitor', namespace)
        self.sim_time = 0.0
        self.time_origin = time_origin  # a hardware run: run time is wall time since it
        self.estimates: dict[int, TargetEstimate] = {}
        self.expected_nodes = set(expected_nodes)
        self.recorded: dict[str, int] = {}
        self.heard: dict[str, set[tuple[int, str]]] = {}
        self._estimate_topic = self._request_topic = self._observation_topic = ''
        self._asked: dict[int, tuple[str, ...]] = {}  # demand -> the cameras its request asked
        self.ready: set[str] = set()  # nodes whose inputs are matched (activesurv/ready)
        self._origin: tuple[float, float] | None = None  # the xy table's (wall0, rate)
        self._recording: set[str] = set()  # topics the recorder was seen subscribed to

    def on_start(self) -> None:
        node = self.node
        node.create_subscription(String, topics.READY, self._on_ready, qos.LATCHED)
        node.create_subscription(Clock, topics.CLOCK, self._on_clock, qos.CLOCK_SUBSCRIBER)
        # Chaos and the end of a run act on simulated time: the table's mapping, not the ticks.
        node.create_subscription(
            Float64MultiArray, topics.CLOCK_ORIGIN, self._on_origin, qos.LATCHED
        )
        node.create_subscription(String, topics.RECORDER_STATUS, self._on_recorder, 10)
        # Per-demand events heard here, by resolved topic name: the run stops only once the
        # recorder has as many of each (a reliable reader holds every message after a lost one
        # until the writer repairs it, which over a loaded network can take seconds). The
        # observations are not read here (one delivery fewer of each at the instants; its effect
        # on the latency is within the runs' spread, docs/performance.md): those of a demand are
        # its request's cameras that its estimate does not name missing.
        self._estimate_topic = node.resolve_topic_name(topics.TARGET_ESTIMATE)
        self._request_topic = node.resolve_topic_name(topics.CAPTURE_REQUEST)
        self._observation_topic = node.resolve_topic_name(topics.MARKER_OBSERVATIONS)
        self.heard = {self._estimate_topic: set(), self._request_topic: set()}
        node.create_subscription(
            TargetEstimate, topics.TARGET_ESTIMATE, self._on_estimate, qos.EVENTS_LATCHED
        )
        node.create_subscription(
            CaptureRequest, topics.CAPTURE_REQUEST, self._on_request, qos.EVENTS_LATCHED
        )

    def _on_request(self, msg: CaptureRequest) -> None:
        index = int(msg.demand_index)
        self.heard[self._request_topic].add((index, ''))
        self._asked[index] = tuple(str(c) for c in msg.camera_ids)

    def observations_expected(self) -> set[tuple[int, str]]:
        """(demand, camera) of every observation fusion had when it decided a demand heard
        here: the cameras asked (as heard) less those its estimate names missing."""
        return {
            (index, camera)
            for index, estimate in self.estimates.items()
            for camera in self._asked.get(index, ())
            if camera not in estimate.cameras_missing
        }

    def _on_ready(self, msg: String) -> None:
        self.ready.add(msg.data.rsplit('/', 1)[-1])

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.sec + 1e-9 * msg.clock.nanosec

    def _on_recorder(self, msg: String) -> None:
        with contextlib.suppress(ValueError, AttributeError):
            self.recorded = {str(k): int(v) for k, v in json.loads(msg.data).items()}

    def _on_estimate(self, msg: TargetEstimate) -> None:
        self.estimates[int(msg.demand_index)] = msg
        self.heard[self._estimate_topic].add((int(msg.demand_index), ''))

    def unrecorded(self) -> dict[str, int]:
        """Per-demand event topics with messages heard here but not (yet) in the bag."""
        heard = {**self.heard, self._observation_topic: self.observations_expected()}
        out = {t: len(k) - self.recorded.get(t, 0) for t, k in heard.items()}
        return {t: n for t, n in out.items() if n > 0}

    def _on_origin(self, msg: Float64MultiArray) -> None:
        if len(msg.data) >= 2 and all(math.isfinite(v) for v in msg.data[:2]) and msg.data[1] > 0:
            self._origin = (float(msg.data[0]), float(msg.data[1]))

    def on_spin(self) -> None:
        if self.time_origin is not None:
            self.sim_time = time.time() - self.time_origin
        elif self._origin is not None:  # between /clock ticks (0.4 s apart): the owner's mapping
            wall0, rate = self._origin
            self.sim_time = max(self.sim_time, (time.monotonic() - wall0) * rate)

    def missing_nodes(self) -> set[str]:
        return self.missing(self.expected_nodes)

    def unrecorded_topics(self, exclude: Collection[str], recorder: str = 'recorder') -> set[str]:
        """Topics with a publisher that ``recorder`` does not subscribe to yet (``exclude``:
        the topics it is told to leave out)."""
        node, out = self.node, set[str]()
        for topic, _ in node.get_topic_names_and_types():
            if topic in exclude or topic in self._recording:
                continue
            if not node.get_publishers_info_by_topic(topic):
                continue
            if any(i.node_name == recorder for i in node.get_subscriptions_info_by_topic(topic)):
                self._recording.add(topic)  # a subscription stays: not asked again
            else:
                out.add(topic)
        return out

    def release_time(self) -> None:
        """Let a held simulated xy table start the time (latched: heard however late)."""
        self.node.create_publisher(Empty, topics.TIME_RELEASE, qos.LATCHED).publish(Empty())


def _chaos(
    launcher: Launcher,
    kills: Sequence[Kill],
    killed: set[Kill],
    restarted: set[Kill],
    specs: dict[str, NodeSpec],
    sim_time: float,
    progress: Progress,
) -> None:
    """Kill and restart nodes when simulated time reaches their instants."""
    for k in kills:
        fqn = specs[k.node].fqn
        if k not in killed and sim_time >= k.at:
            proc = launcher.processes[fqn]
            proc.stopped_on_purpose = True
            proc.kill()
            killed.add(k)
            progress(f'killed {k.node} (SIGKILL) at simulated time {sim_time:.2f} s')
        due = k.restart_at is not None and sim_time >= k.restart_at
        if due and k in killed and k not in restarted:
            launcher.processes[fqn].process.wait(5.0)
            launcher.start_node(specs[k.node])
            restarted.add(k)
            progress(f'restarted {k.node} at simulated time {sim_time:.2f} s')


@dataclass(frozen=True)
class Until:
    """When a graph run ends, and what it says meanwhile.

    Attributes:
        done: True when the run should end (the monitor shows simulated time and estimates).
        wall_limit: wall seconds after simulated time starts at which the run is failed.
        report: a progress line, or None when there is nothing new to say.
    """

    done: Callable[[Any], bool]
    wall_limit: float
    report: Callable[[Any], str | None]


def experiment_until(exp: Experiment, rtf: float) -> Until:
    """An experiment ends when every demand has an answer (or its time is long past)."""
    m = len(exp.demand_times)
    end_sim = exp.demand_times[-1] + exp.fusion_config().collect_timeout + 2.0
    shown = [-1]

    def report(mon: Any) -> str | None:
        if len(mon.estimates) == shown[0]:
            return None
        shown[0] = len(mon.estimates)
        clock = 'run' if mon.time_origin is not None else 'simulated'
        return f'demand {shown[0]} of {m} answered, {clock} time {mon.sim_time:.1f} s'

    return Until(
        lambda mon: len(mon.estimates) >= m or mon.sim_time >= end_sim,
        (end_sim / max(rtf, 1e-3)) * 3.0 + 60.0,
        report,
    )


def run_graph(
    exp: Experiment,
    out_dir: Path,
    options: RunOptions | None = None,
    progress: Progress = print,
    hosts: NetnsHosts | None = None,
    until: Until | None = None,
    specs: list[NodeSpec] | None = None,
    before_start: Callable[[RunMonitor, Progress], None] | None = None,
) -> Path:
    """Run ``exp`` as a node graph; returns the bag directory.

    With ``options.compose`` every node runs in this process on one executor instead of in its
    own process. ``options.kills`` SIGKILL nodes at simulated instants and restart them (chaos
    testing). ``options.extra`` nodes (e.g. load generators) start with the graph;
    ``options.thin`` topics are thinned in the bag. With ``hosts`` (namespaces ``core``,
    ``cam1`` ...; this process must already be in ``core``) every camera's nodes run on their
    own host.

    ``until`` replaces the experiment's end (every demand answered); ``specs`` replaces the
    experiment's nodes (as :func:`graph_specs` would list them, xy table last);
    ``before_start(monitor, progress)`` runs when every node is up, before the last one starts
    (a hardware run places its cameras there).

    Raises:
        ConfigError: for options that do not fit this run (a node to kill that is not in it).
        NodeDiedError: if a node dies, or the graph does not come up in time.
    """
    opts = options or RunOptions()
    out_dir.mkdir(parents=True, exist_ok=True)
    bag = out_dir / 'bag'
    if bag.exists():
        raise ConfigError(f'{bag} exists: give a new --out directory')
    if specs is None:
        specs = graph_specs(
            exp,
            bag,
            opts.rtf,
            opts.image_rate,
            opts.faults,
            opts.thin,
            split_hosts=hosts is not None,
            preview_rate=opts.preview_rate,
        )
    if opts.extra:
        specs = specs[:-1] + list(opts.extra) + specs[-1:]
    by_name = {s.name: s for s in specs[:-1]}
    for k in opts.kills:
        if k.node not in by_name:
            raise ConfigError(f'cannot kill {k.node}: it is not running in this run')
    if opts.processes == 'containers' and not opts.compose:
        alone = [k.node for k in opts.kills] + [s.name for s in opts.extra]
        specs = group_processes(specs[:-1], alone) + specs[-1:]
    rule = until or experiment_until(exp, opts.rtf)
    with scoped_environ(opts.environment()):
        return _run(out_dir, bag, specs, by_name, opts, progress, hosts, rule, before_start)


def _run(
    out_dir: Path,
    bag: Path,
    specs: list[NodeSpec],
    by_name: dict[str, NodeSpec],
    opts: RunOptions,
    progress: Progress,
    hosts: NetnsHosts | None,
    until: Until,
    before_start: Callable[[RunMonitor, Progress], None] | None = None,
) -> Path:
    startup_timeout = opts.startup_timeout
    (out_dir / 'logs').mkdir(exist_ok=True)
    env = dict(os.environ)
    timed = callback_cpu.enabled() and not opts.compose  # each process's callbacks' CPU
    if timed:
        env[callback_cpu.ENV] = str(out_dir / 'logs' / 'callbacks')
    table = _held_for_clock(specs, opts)
    # The simulated table starts with the graph and holds time at 0 until released below:
    # its own start (imports, error maps: 0.6 s of a core) overlaps the others'.
    early = _owns_clock(specs[-1], opts)
    if early:
        table = replace(table, parameters={**table.parameters, 'hold_until_released': True})
    first = [*specs[:-1], table] if early else specs[:-1]
    monitor = RunMonitor(
        [m.name for s in first for m in (s.members or (s,))],
        opts.time_origin,
        opts.namespace,
    )
    # rclpy is started with the monitor when no one in this process has; the callbacks' CPU is
    # collected once every process has stopped, a signalled run's too.
    with _callbacks_into(out_dir, timed), monitor:
        launcher: NodeRunner
        if opts.compose:
            launcher = Composition()  # every node's module in-process
        else:
            prefixes = (
                {h: hosts.prefix(h) for h in hosts.names if h != 'core'} | {'core': []}
                if hosts is not None
                else None
            )
            launcher = Launcher(first, workdir=out_dir / 'logs', env=env, hosts=prefixes)
        # SIGINT, SIGTERM and SIGHUP stop the run cleanly: the graph is drained and stopped,
        # then StopRequested (the bag is closed by then).
        with GraphSession(
            launcher, first, monitor.missing_nodes, monitor.spin, startup_timeout
        ) as graph:
            if before_start is not None:
                before_start(monitor, progress)
            n_nodes = sum(len(s.members) or 1 for s in specs)
            if opts.time_origin is None:
                _wait_until_matched(graph, monitor, first, progress)
                _wait_until_recorded(graph, monitor, first, progress)
            if early:
                progress(f'{n_nodes} nodes up in {len(specs)} processes; simulated time starts')
                graph.raise_if_stopping()
                monitor.release_time()
            else:
                last = (
                    'the xy table and simulated time'
                    if opts.time_origin is None
                    else specs[-1].name
                )
                progress(f'{n_nodes} nodes up in {len(specs) - 1} processes; starting {last}')
                graph.raise_if_stopping()
                graph.start([table])
            _watch(graph, launcher, monitor, until, opts, by_name, progress, out_dir)
    return bag


@contextlib.contextmanager
def _callbacks_into(out_dir: Path, timed: bool) -> Iterator[None]:
    """On the way out, ``cpu.json`` gets each process's callbacks' CPU
    (``ACTIVESURV_CALLBACK_CPU``, written by the processes as they stopped): every process's
    tally under ``callbacks``, the costliest under ``top_callbacks``."""
    try:
        yield
    finally:
        cpu_file = out_dir / 'cpu.json'
        collected = callback_cpu.collect(out_dir / 'logs' / 'callbacks') if timed else {}
        if collected and cpu_file.is_file():
            doc = json.loads(cpu_file.read_text())
            doc['top_callbacks'] = callback_cpu.top(collected)
            doc['callbacks'] = collected
            cpu_file.write_text(json.dumps(doc, indent=2) + '\n')


READY_MODULES = ('activesurv_prediction.predictor_node',)
"""Nodes that say when their inputs are matched (:mod:`activesurv_common.ros.ready`); and
every node given ``wait_for_readers`` or ``announce_ready`` (fusion)."""
READY_TIMEOUT = 15.0
"""s (wall) simulated time waits for them before it starts anyway, with a warning."""


def _wait_until_matched(
    graph: GraphSession, monitor: RunMonitor, specs: Sequence[NodeSpec], progress: Progress
) -> None:
    """Hold simulated time until every node of :data:`READY_MODULES` and every node given
    ``wait_for_readers`` says its topics are matched (``activesurv/ready``): a fix published
    before the locator's writer and the predictor's reader have matched is lost, and with it
    the track of the first demand (one Set A fast run in ten lost demand 0 so: its fixes
    reached the predictor only 1.5 s into simulated time). A run on a rig's wall clock does
    not wait."""
    expected = {
        m.name
        for s in specs
        for m in (s.members or (s,))
        if m.module in READY_MODULES
        or int(m.parameters.get('wait_for_readers', 0)) > 0
        or bool(m.parameters.get('announce_ready', False))
    }
    started = time.monotonic()
    while not expected <= monitor.ready:
        graph.raise_if_stopping()
        if time.monotonic() > started + READY_TIMEOUT:
            late = ', '.join(sorted(expected - monitor.ready))
            progress(f'warning: {late}: inputs not matched after {READY_TIMEOUT:g} s; starting')
            return
        monitor.spin(0.02)
    if (waited := time.monotonic() - started) >= 0.1:
        progress(f'{", ".join(sorted(expected))}: inputs matched {waited:.1f} s after the nodes')


def _wait_until_recorded(
    graph: GraphSession, monitor: RunMonitor, specs: Sequence[NodeSpec], progress: Progress
) -> None:
    """Hold simulated time until the recorder subscribes to every topic published so far: it
    finds topics by polling the graph, and a camera whose container came up last had its
    first two frames unrecorded (a replay of that bag then missed them)."""
    recorder = next((s for s in specs if s.name == 'recorder'), None)
    if recorder is None:
        return
    exclude = set(recorder.parameters.get('exclude', ()))
    exclude.add(monitor.node.resolve_topic_name(topics.RECORDER_STATUS))  # never its own
    started = time.monotonic()
    while missing := monitor.unrecorded_topics(exclude):
        graph.raise_if_stopping()
        if time.monotonic() > started + READY_TIMEOUT:
            late = ', '.join(sorted(missing))
            progress(f'warning: the recorder does not record {late} after {READY_TIMEOUT:g} s')
            return
        monitor.spin(0.1)
    if (waited := time.monotonic() - started) >= 0.1:
        progress(f'the recorder records every topic {waited:.1f} s after the inputs matched')


def _watch(
    graph: GraphSession,
    launcher: NodeRunner,
    monitor: RunMonitor,
    until: Until,
    opts: RunOptions,
    by_name: dict[str, NodeSpec],
    progress: Progress,
    out_dir: Path,
) -> None:
    """Run until ``until`` says done (or a signal), chaos and resource samples on the way; then
    drain the recorder and write ``cpu.json`` (and ``resources.json``)."""
    killed: set[Kill] = set()
    restarted: set[Kill] = set()
    cpu0, wall0 = _cpu(launcher), time.monotonic()
    running: list[tuple[dict[str, float], float]] = []  # at RUNNING_FROM s simulated, at the end
    wall_limit = time.monotonic() + until.wall_limit
    samples: list[dict[str, Any]] = []
    next_sample = wall0
    while not until.done(monitor):
        if not running and monitor.sim_time >= RUNNING_FROM:
            running.append((_cpu(launcher), time.monotonic()))
        if graph.stopping:
            progress(
                f'{graph.stopping} at simulated time {monitor.sim_time:.1f} s: stopping '
                '(open demands are answered, the bag is closed)'
            )
            break
        if time.monotonic() >= next_sample and not opts.compose:
            next_sample += RESOURCE_PERIOD
            samples.append(_resources(launcher, wall0, monitor.sim_time))
        if opts.kills:  # RunOptions refuses kills with compose: these are processes
            assert isinstance(launcher, Launcher)
            _chaos(launcher, opts.kills, killed, restarted, by_name, monitor.sim_time, progress)
        graph.check()
        monitor.spin_batched(0.25)  # not woken by every observation at the demand instants
        line = until.report(monitor)
        if line:
            progress(line)
        if time.monotonic() > wall_limit:
            raise NodeDiedError(
                f'the run did not finish in time (simulated time {monitor.sim_time:.1f} s '
                f'after {until.wall_limit:.0f} s of wall time)'
            )
    if running:
        running.append((_cpu(launcher), time.monotonic()))
    # Stop only when the recorder has every request, observation and estimate heard here
    # (a restarted node is matched late; a lost datagram holds a reliable reader's later
    # messages until the writer's next heartbeat repairs it).
    drain = 3.0 if graph.stopping else 20.0  # a signalled run exits within 10 s
    deadline = time.monotonic() + drain
    while missing := monitor.unrecorded():
        if time.monotonic() > deadline:
            progress(f'the recorder is missing {missing} after {drain:.0f} s; stopping anyway')
            break
        monitor.spin(0.25)
    monitor.spin(0.5)  # the recorder gets the last messages
    _write_cpu(out_dir / 'cpu.json', cpu0, _cpu(launcher), time.monotonic() - wall0, running)
    if samples:
        (out_dir / 'resources.json').write_text(json.dumps({'samples': samples}) + '\n')


def clock_readers(specs: Sequence[NodeSpec]) -> int:
    """The /clock subscriptions the processes of ``specs`` start with: one per simulated-time
    node, one per container holding any (its members share it: ``compose.share_clock``)."""

    def sim(s: NodeSpec) -> bool:
        return bool(s.parameters.get('use_sim_time'))

    return sum(1 for s in specs if (any(sim(m) for m in s.members) if s.members else sim(s)))


def _held_for_clock(specs: Sequence[NodeSpec], opts: RunOptions) -> NodeSpec:
    """The last spec; the simulated xy table holds time at 0 until every process's /clock
    reader (and this one's monitor's) has matched its writer, as it does for its object
    readers: one matched late stays at time 0 while the rest run (at rtf 3 a dispatcher at
    t = 0 for 8 simulated seconds answered seven demands with no camera)."""
    table = specs[-1]
    if not _owns_clock(table, opts):
        return table
    readers = clock_readers(specs[:-1]) + 1  # + the monitor
    return replace(table, parameters={**table.parameters, 'wait_for_clock_subscribers': readers})


def _owns_clock(table: NodeSpec, opts: RunOptions) -> bool:
    """``table`` is the simulated xy table owning /clock, in a process of its own."""
    return (
        table.module == 'activesurv_sim.xy_table_node'
        and not opts.compose
        and bool(table.parameters.get('publish_clock', True))
        and opts.time_origin is None
    )


RESOURCE_PERIOD = 10.0  # wall s between samples of each process's memory and CPU
RUNNING_FROM = 1.0  # simulated s: past the start's burst (discovery, the first frames)


def _resources(launcher: NodeRunner, wall0: float, sim_time: float) -> dict[str, Any]:
    """One sample of ``resources.json``: wall and simulated time, RSS (MB) and CPU (s)."""
    return {
        'wall': round(time.monotonic() - wall0, 2),
        'sim': round(sim_time, 2),
        'rss_mb': {k: round(v / 2**20, 2) for k, v in launcher.rss_bytes().items()},
        'cpu_s': {k: round(v, 2) for k, v in launcher.cpu_seconds().items()},
    }


def _cpu(launcher: NodeRunner) -> dict[str, float]:
    """CPU seconds so far of each node process, and of this (orchestrating) process."""
    own = os.times()
    return {'orchestrator': own.user + own.system, **launcher.cpu_seconds()}


def _write_cpu(
    path: Path,
    before: dict[str, float],
    after: dict[str, float],
    wall: float,
    running: Sequence[tuple[dict[str, float], float]] = (),
) -> None:
    """CPU use of the run from the graph's start (its processes up, before simulated time
    starts) to its end, the recorder drained (``cpu.json``).

    ``cores`` is CPU seconds of all processes over wall seconds: 1.0 is one core kept busy.
    A node restarted mid-run counts from its restart. ``running`` (given two samples) is the
    same from ``RUNNING_FROM`` s of simulated time to the last demand: the rate a running
    graph keeps, without the start's discovery burst or the idle drain, whose share of a short
    run's window changes ``cores`` from one run to the next.
    """
    used = {k: round(after[k] - before.get(k, 0.0), 3) for k in sorted(after)}
    doc: dict[str, Any] = {
        'wall_seconds': round(wall, 3),
        'cpu_seconds': used,
        'cores': round(sum(used.values()) / max(wall, 1e-9), 3),
    }
    if len(running) == 2 and running[1][1] > running[0][1]:
        (c0, w0), (c1, w1) = running
        spent = sum(c1[k] - c0.get(k, 0.0) for k in c1)
        doc['running'] = {
            'from_sim_time': RUNNING_FROM,
            'wall_seconds': round(w1 - w0, 3),
            'cpu_seconds': round(spent, 3),
            'cores': round(spent / (w1 - w0), 3),
        }
    path.write_text(json.dumps(doc, indent=2) + '\n')
