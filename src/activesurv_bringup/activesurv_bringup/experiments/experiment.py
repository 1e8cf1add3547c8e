"""Experiment definitions: the paper's Sets A and B for the static, medium and fast systems.

An :class:`Experiment` holds everything one run needs, whether it runs as a node graph or in
lockstep: the object's actual path and the path the initial placement assumes, the demand
instants, the camera set-up with its initial poses, and the tuning of every module. The initial
poses come from the dispatcher's initial-pose determination and are cached on disk, keyed by the
inputs that determine them.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.experiments.faults import Fault, imager_injection
from activesurv_bringup.files import cache_dir, config_path
from activesurv_bringup.rig.rigs import RigChoice
from activesurv_common.camera_model import CameraModel, overhead_camera
from activesurv_common.geometry import Transform, matrix_from_quaternion
from activesurv_common.mount import CameraMount
from activesurv_common.object_geometry import ObjectGeometry
from activesurv_common.occlusion import obstacles_to_list
from activesurv_common.sensor_model import SensorModel
from activesurv_dispatch.errors import DispatchConfigError
from activesurv_dispatch.initial_pose import initial_poses
from activesurv_dispatch.planner import Demand
from activesurv_dispatch.sensors import Setup, default_setup_path, load_setup, setup_to_dict
from activesurv_dispatch.session import DispatcherConfig
from activesurv_fusion.config import FusionConfig
from activesurv_imaging.imager_config import ImagerConfig
from activesurv_prediction.session import PredictorConfig
from activesurv_recording.run_record import ExperimentRun, RigFacts, RunRecord
from activesurv_sim.xytable import (
    TableConfig,
    TimedPath,
    XYTable,
    from_csv,
    named_path,
)
from activesurv_stages.errors import ConfigError as StageConfigError

SETS = ('A', 'B')
SYSTEMS = ('static', 'medium', 'fast')


@dataclass(frozen=True)
class Experiment:
    """One run of the paper's experiments (everything in SI units)."""

    set_name: str
    system: str
    seed: int
    config: dict[str, Any]
    actual_spec: dict[str, Any]  # how the xy table is programmed: type, points or csv
    actual: TimedPath
    expected: TimedPath
    demand_times: tuple[float, ...]
    setup: Setup  # what the system believes: the calibration's mounts and intrinsics
    model: SensorModel
    rig: RigChoice | None = None  # the simulated hardware; None: exactly the set-up (round 1)

    @property
    def object_model(self) -> ObjectGeometry:
        o = self.config['object']
        r = self.setup.marker_radius  # both markers: Table I's 25 mm discs
        return ObjectGeometry(
            float(o['top_height']),
            tuple(o['side_offset']),
            tuple(o['side_normal']),
            side_radius=r,
            top_radius=r,
        )

    @property
    def start_time(self) -> float:
        return float(self.config['object']['start_time'])

    @property
    def object_speed(self) -> tuple[float, float]:
        """The object's path speed (m/s) and acceleration (m/s^2)."""
        o = self.config['object']
        return float(o['speed']), float(o['acceleration'])

    @property
    def overhead_rate(self) -> float:
        """Frames per second of the overhead camera."""
        return float(self.config['overhead']['rate'])

    @property
    def plan_latency(self) -> float:
        """Lockstep only: s between an overhead frame and the plan made on it."""
        return float(self.config.get('lockstep', {}).get('plan_latency', 0.0))

    def with_predictor(self, model: str) -> Experiment:
        """The same experiment with another prediction model (``imm`` or ``ca``)."""
        config = {**self.config, 'predictor': {**self.config['predictor'], 'model': model}}
        return replace(self, config=config)

    def table_config(self) -> TableConfig:
        """What the xy table is told in this experiment: the actual path, the object."""
        obj, spec = self.config['object'], self.actual_spec
        csv = spec['type'] == 'csv'
        return TableConfig(
            str(spec['type']),
            () if csv else tuple(float(v) for v in spec['points']),
            str(spec['csv']) if csv else '',
            float(obj['speed']),
            float(obj['acceleration']),
            self.start_time,
            bool(obj.get('enters_at_start', False)),
            self.object_model,
        )

    def table(self, expected: bool = False) -> XYTable:
        """The object on the xy table (the actual path with the rig's table errors)."""
        if expected:
            return XYTable(self.expected, self.start_time, self.object_model)
        error = self.rig.rig.table_offset if self.rig is not None else None
        c = self.table_config()
        return XYTable(self.actual, c.start_time, c.model, error, c.enters_at_start)

    def true_camera(self, camera_id: str) -> tuple[CameraModel, CameraMount]:
        """A dynamic camera as it really is: the rig's optics and mount with stage errors."""
        if self.rig is None:
            s = self.setup.sensor(camera_id)
            return s.camera, s.mount
        rc = self.rig.rig.camera(camera_id)
        return rc.camera, rc.true_mount()

    def overhead(self, truth: bool) -> tuple[CameraModel, Transform]:
        """The overhead camera's optics and pose: as they are, or as the system believes."""
        if self.rig is not None:
            if truth:
                return self.rig.rig.overhead, self.rig.rig.overhead_pose
            return self.rig.calibration.overhead, self.rig.calibration.overhead_pose
        pose = [float(v) for v in self.config['overhead']['pose']]
        return overhead_camera(), Transform.from_rt(matrix_from_quaternion(pose[3:]), pose[:3])

    def demands_on(self, expected: bool) -> list[Demand]:
        """Demand points along the actual or expected path (truth for evaluation/placement)."""
        table = self.table(expected)
        cov = np.diag([1e-6] * 3 + [1e-4] * 3)
        out = []
        for j, t in enumerate(self.demand_times):
            s = table.state(t)
            out.append(Demand(j, t, s.side.copy(), s.side_normal.copy(), cov))
        return out

    @property
    def end_time(self) -> float:
        return self.demand_times[-1] + 1.0

    def predictor_config(self, demand_times: Sequence[float] | None = None) -> PredictorConfig:
        """What the predictor is told in this experiment (the typed run description: the one
        place that reads the experiments YAML's predictor and object keys)."""
        pc, obj = self.config['predictor'], self.config['object']
        times = self.demand_times if demand_times is None else demand_times
        return PredictorConfig(
            model=str(pc.get('model', 'imm')),
            measurement_std=float(pc['measurement_std']),
            jerk_std=float(pc['jerk_std']),
            confirm_fixes=int(pc['confirm_fixes']),
            horizon=int(pc['horizon']),
            marker_height=float(obj['top_height']),
            side_offset=_three(obj['side_offset']),
            side_normal=_three(obj['side_normal']),
            demand_times=tuple(float(t) for t in times),
        )

    def dispatcher_config(self, camera_timeout: float = 0.5) -> DispatcherConfig:
        """What the dispatcher is told in this experiment."""
        dc = self.config['dispatch']
        return DispatcherConfig(
            int(self.config['k']),
            float(dc['rho']),
            float(dc['capture_lead']),
            float(dc['settle_time']),
            camera_timeout,
        )

    def fusion_config(self) -> FusionConfig:
        """What the fusion node is told in this experiment."""
        fc = self.config['fusion']
        return FusionConfig(float(fc['collect_timeout']), float(fc['z_sigma']))

    def imager_config(self, camera_id: str, fault: Fault | None = None) -> ImagerConfig:
        """What camera ``camera_id``'s imager is told in this simulated experiment (with its
        injected fault, if any): its stages latch their state at each instant."""
        # The exposure the camera is set to (the lab sets it; a streak is taken out over it)
        # and its response as calibrated (commissioning estimates it).
        exposure = self.rig.rig.camera(camera_id).lens.exposure_time if self.rig else 0.0
        gamma = self.rig.calibration.cameras[camera_id].gamma if self.rig else 0.0
        return ImagerConfig(
            camera_id,
            self.setup.marker_radius,
            exact_state=True,
            exposure_time=exposure,
            gamma=gamma,
            obstacles=self.setup.obstacles,
            **imager_injection(fault),  # type: ignore[arg-type]
        )

    def record(
        self, faults: Sequence[Fault] = (), execution: Literal['graph', 'lockstep'] = 'graph'
    ) -> RunRecord:
        """The run record of this experiment (what the bag and ``results.json`` say of it)."""
        return RunRecord(
            run=ExperimentRun(
                set_name=self.set_name,
                execution=execution,
                demand_times=tuple(self.demand_times),
                faults=tuple(str(f) for f in faults),
                object=dict(self.config['object']),
            ),
            **self.record_facts(),
        )

    def record_facts(self) -> dict[str, Any]:
        """The run record's fields every run of this experiment's rig shares (a session's too)."""
        return {
            'system': self.system,
            'seed': self.seed,
            'predictor': str(self.config['predictor'].get('model', 'imm')),
            'marker_radius': self.setup.marker_radius,
            'initial_poses': {
                c: tuple(float(v) for v in q) for c, q in self.setup.initial.items()
            },
            'rig': RigFacts.model_validate(self.rig.describe() if self.rig is not None else {}),
            # What the system was told: a replay's imagers are told the same.
            'setup': setup_to_dict(self.setup) if self.rig is not None else None,
            'obstacles': tuple(obstacles_to_list(self.setup.obstacles)),
            'imager_optics': {
                s.camera_id: {
                    'exposure_time': (c := self.imager_config(s.camera_id)).exposure_time,
                    'gamma': c.gamma,
                }
                for s in self.setup.sensors
            },
        }


def _three(v: Any) -> tuple[float, float, float]:
    x = [float(a) for a in v]
    if len(x) != 3:
        raise ConfigError(f'expected 3 numbers, got {v!r}')
    return x[0], x[1], x[2]


def _path(spec: dict[str, Any], obj: dict[str, Any]) -> TimedPath:
    return named_path(
        str(spec['type']),
        list(spec.get('points', [])),
        float(obj['speed']),
        float(obj['acceleration']),
        str(spec.get('csv', '')),
    )


def _cached_initial(
    setup: Setup, model: SensorModel, expected: list[Demand], k: int, key_extra: str
) -> dict[str, np.ndarray]:
    h = hashlib.sha256()
    h.update(default_setup_path().read_bytes())
    h.update(key_extra.encode())
    h.update(np.array(model.coefficients).tobytes())
    for d in expected:
        h.update(np.r_[d.time, d.position, d.normal].tobytes())
    path = cache_dir() / 'initial_poses' / f'{h.hexdigest()[:24]}.json'
    try:
        data = json.loads(path.read_text())
        return {c: np.array(v, dtype=float) for c, v in data.items()}
    except (OSError, ValueError):
        pass
    poses = initial_poses(setup, model, expected, 0.0, k)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({c: [float(v) for v in q] for c, q in poses.items()}))
    except OSError:
        pass  # a read-only home: just recompute next time
    return poses


def load_experiment(
    set_name: str,
    system: str,
    seed: int = 0,
    trajectory: str | None = None,
    expect: str | None = None,
    config_file: Path | None = None,
    rig: RigChoice | None = None,
) -> Experiment:
    """Build one experiment.

    Args:
        set_name: ``A`` or ``B``.
        system: ``static``, ``medium`` or ``fast``.
        seed: seeds image noise (and anything else random).
        trajectory: a ``t,x,y`` CSV replacing the object's actual path.
        expect: ``parabolic``, ``diagonal`` or a CSV path: the path initial placement assumes.
        config_file: experiments YAML (default: the packaged one).
        rig: the simulated hardware and the calibration the system uses (None: the set-up
            itself is the truth, as in round 1).

    Raises:
        ConfigError: for an unknown set or system, or a bad path or config.
    """
    if set_name not in SETS:
        raise ConfigError(f'unknown set {set_name!r}; choose from {SETS}')
    if system not in SYSTEMS:
        raise ConfigError(f'unknown system {system!r}; choose from {SYSTEMS}')
    path = config_file or config_path()
    try:
        cfg = yaml.safe_load(Path(path).read_text())
        obj = cfg['object']
        paths = cfg['paths']
        chosen = cfg['sets'][set_name]
        actual_spec = (
            {'type': 'csv', 'csv': str(Path(trajectory).resolve())}
            if trajectory
            else dict(paths[chosen['actual']])
        )
        actual = from_csv(trajectory) if trajectory else _path(actual_spec, obj)
        if expect is None:
            expected = _path(paths[chosen['expected']], obj)
        elif expect in paths:
            expected = _path(paths[expect], obj)
        else:
            expected = from_csv(expect)
        dm = cfg['demands']
        times = tuple(
            float(dm['first']) + i * float(dm['interval']) for i in range(int(dm['count']))
        )
        k = int(cfg['k'])
    except StageConfigError as exc:
        raise ConfigError(str(exc)) from exc
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise ConfigError(f'experiment config {path}: {exc!r}') from exc
    model = SensorModel.load()
    setup = load_setup(rig.layout if rig is not None else None, motion=system)
    belief = ''
    if rig is not None:
        try:
            setup = setup.calibrated(rig.calibration.mounts, rig.calibration.cameras)
            setup = setup.with_obstacles(rig.rig.obstacles)  # the cell's fixtures are known
        except DispatchConfigError as exc:
            raise ConfigError(str(exc)) from exc
        believed = setup_to_dict(setup)
        if not believed['obstacles']:  # (placements cached before obstacles existed stay valid)
            del believed['obstacles']
        belief = json.dumps(believed, sort_keys=True)
    exp = Experiment(
        set_name, system, seed, cfg, actual_spec, actual, expected, times, setup, model, rig
    )
    placed = _cached_initial(
        setup,
        model,
        exp.demands_on(expected=True),
        k,
        f'{system}|{json.dumps(cfg, sort_keys=True)}|{expect}|{belief}',
    )
    return Experiment(
        set_name,
        system,
        seed,
        cfg,
        actual_spec,
        actual,
        expected,
        times,
        setup.with_initial(placed),
        model,
        rig,
    )
