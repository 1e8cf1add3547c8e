"""The run record: what a run was, written once into its bag and read by every evaluator.

One frozen record (pydantic) goes from the CLI to ``results.json``: the orchestrator builds
it from the experiment or session, the recorder stores it on ``/activesurv/run_info`` (JSON),
and the evaluators, the report and a replay read it back with :func:`read_run_record`. Its
``run`` is a tagged union (``kind``): an :class:`ExperimentRun` (a set's fixed demand
instants, run as a graph or in lockstep) or a :class:`SessionRun` (a stream of objects, demands
per object). Where it ran and how are two more facts beside it: ``hardware`` (an
:class:`OnRig`: the hardware file, its namespace, the wall-clock origin) for a run on a real
rig, and ``replayed`` for the output of a replay. :attr:`RunRecord.kind` names the four
kinds a reader meets: ``experiment``, ``session``, ``hardware run`` and ``replay``.

``to_json``/``from_json`` keep writing and reading together. Bags recorded before the record
existed hold a looser dict keyed by a ``mode`` string; :meth:`RunRecord.from_json` reads those
too (the only place that knows their keys), so ``activesurv report`` renders old runs.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, Literal

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from activesurv_common.ros import topics
from activesurv_recording.bagio import read_bag
from activesurv_recording.errors import BagError

VERSION: Literal[1] = 1


class _Frozen(BaseModel):
    model_config = ConfigDict(extra='forbid', frozen=True)


class RigFacts(_Frozen):
    """The simulated rig and what the system was told (all None: the paper's nominal set-up)."""

    rig: str | None = None
    rig_source: str | None = None
    rig_seed: int | None = None
    calibration: str | None = None


class OnRig(_Frozen):
    """A run on a real rig, on the wall clock."""

    hardware: str  # the hardware file
    name: str  # the rig's name (the file's ``name``)
    namespace: str = ''
    time_origin: float  # wall-clock s of run time 0 (demand instants are run times)
    truth: str | None = None  # where the truth comes from (a table controller), None: none
    # What each imager was told, so that a replay of the recorded frames measures alike.
    imagers: dict[str, dict[str, Any]] = Field(default_factory=dict)


class ExperimentRun(_Frozen):
    """One of the paper's sets (or a trajectory of the user's): fixed demand instants."""

    kind: Literal['experiment'] = 'experiment'
    set_name: str
    execution: Literal['graph', 'lockstep'] = 'graph'
    demand_times: tuple[float, ...]
    faults: tuple[str, ...] = ()
    object: dict[str, Any] = Field(default_factory=dict)  # the set's object configuration


class StreamFacts(_Frozen):
    """The session's object stream (it is regenerated from these to evaluate the session)."""

    seed: int
    arrival_interval: float
    first_entry: float
    kinds: tuple[str, ...]
    at_once: int = 1
    speed: float
    acceleration: float
    script: tuple[dict[str, Any], ...] = ()


class DemandRule(_Frozen):
    """How a session's demands are made: every ``interval`` s or at the ``lines_x`` lines."""

    mode: Literal['interval', 'lines']
    interval: float
    lines_x: tuple[float, ...] = ()
    region: tuple[float, ...] = ()


class SessionRun(_Frozen):
    """Continuous surveillance: objects cross one after another, demands per object."""

    kind: Literal['session'] = 'session'
    set_name: str | None = None  # a named scene (Set C), or None
    duration: float | None = None  # s of run time; None: until stopped
    stream: StreamFacts
    demands: DemandRule


class RunRecord(_Frozen):
    """What a run was: see the module."""

    record: Literal[1] = VERSION
    run: Annotated[ExperimentRun | SessionRun, Field(discriminator='kind')]
    system: str  # static, medium, fast
    seed: int | None = None
    predictor: str = 'imm'
    marker_radius: float = 0.0125
    initial_poses: dict[str, tuple[float, ...]] = Field(default_factory=dict)
    rig: RigFacts = RigFacts()
    setup: dict[str, Any] | None = None  # what the system was told (replays are told the same)
    obstacles: tuple[
        dict[str, Any], ...
    ] = ()  # the simulated cell's (activesurv_common.occlusion)
    hardware: OnRig | None = None
    # The exposure time and response each simulated run's imager was told (a replay is told
    # the same: the streak taken out, the frames linearised alike).
    imager_optics: dict[str, dict[str, float]] = Field(default_factory=dict)
    replayed: bool = False
    recorder: dict[str, Any] | None = None  # what the recorder noted (``qos: offered``)

    @property
    def kind(self) -> str:
        """``experiment``, ``session``, ``hardware run`` or ``replay``."""
        if self.replayed:
            return 'replay'
        if self.hardware is not None and isinstance(self.run, ExperimentRun):
            return 'hardware run'
        return self.run.kind

    @property
    def mode(self) -> str:
        """What ``results.json`` calls the run's mode (``graph``, ``lockstep``, ``hardware``,
        ``replay``, ``surveil``)."""
        if isinstance(self.run, SessionRun):
            return 'surveil'
        if self.replayed:
            return 'replay'
        return 'hardware' if self.hardware is not None else self.run.execution

    @property
    def time_origin(self) -> float:
        """Run time 0 on the recorded clock: a hardware run's wall clock, else 0."""
        return self.hardware.time_origin if self.hardware is not None else 0.0

    @property
    def truth(self) -> str | None:
        """Where the truth comes from: ``simulator``, a real table's controller, or None."""
        return self.hardware.truth if self.hardware is not None else 'simulator'

    @property
    def imagers(self) -> dict[str, dict[str, Any]]:
        """The parameters each imager of a hardware run was told (empty in simulation)."""
        return dict(self.hardware.imagers) if self.hardware is not None else {}

    @property
    def offered_qos(self) -> bool:
        """Whether the recorder noted the QoS its publishers offered (replay trusts them)."""
        return isinstance(self.recorder, dict) and self.recorder.get('qos') == 'offered'

    def as_replay(self) -> RunRecord:
        return self.model_copy(update={'replayed': True, 'recorder': None})

    def with_hardware(self, on_rig: OnRig) -> RunRecord:
        return self.model_copy(update={'hardware': on_rig})

    def to_json(self) -> str:
        return self.model_dump_json()

    @classmethod
    def from_json(cls, data: str | bytes | dict[str, Any]) -> RunRecord:
        """A record from its JSON (or decoded JSON), this version's or a legacy bag's.

        Raises:
            BagError: for JSON that describes no run.
        """
        try:
            doc = json.loads(data) if isinstance(data, (str, bytes)) else dict(data)
            if not isinstance(doc, dict):
                raise ValueError('not a JSON object')
            if 'record' not in doc:
                doc = _legacy(doc)
            return cls.model_validate(doc)
        except (ValueError, KeyError, TypeError) as exc:
            # ValidationError is a ValueError
            what = exc.error_count() if isinstance(exc, ValidationError) else None
            detail = f'{what} problems: {exc}' if what else str(exc)
            raise BagError(f'not an activesurv run record: {detail}') from exc


def read_run_record(bag: Path) -> RunRecord:
    """The run record stored in ``bag`` (a directory, split or not).

    Raises:
        BagError: for a missing or damaged bag, or one without a run record.
    """
    key = _bag_key(bag)
    text = _RECORDS.get(key) if key is not None else None
    if text is None and key is not None:
        text = _record_from_mcap(bag)
    if text is None:
        for m in read_bag(bag, {topics.RUN_INFO}):
            text = str(m.msg.data)
            break
        else:
            raise BagError(f'bag {bag} has no {topics.RUN_INFO} message (not an activesurv run?)')
        if key is not None:
            _RECORDS[key] = text
            while len(_RECORDS) > 32:
                del _RECORDS[next(iter(_RECORDS))]
    return RunRecord.from_json(text)


# The run record's JSON per closed bag (its path and its metadata file's size and time): opening
# a bag with rosbags parses its metadata (each topic's QoS profiles) with a pure-Python YAML
# reader, 0.6-1.3 s for a run's bag, and evaluating a run asked for its record three times; the
# record is read from the MCAP index instead where it can be.
_RECORDS: dict[tuple[str, int, int], str] = {}


def _record_from_mcap(bag: Path) -> str | None:
    """The run record's JSON read through the MCAP files' own index (milliseconds), or None
    where that does not find it (then the bag is read as a whole, with its errors)."""
    try:
        for path in sorted(Path(bag).glob('*.mcap')):
            with path.open('rb') as f:
                reader = make_reader(f, decoder_factories=[DecoderFactory()])
                for _, _, _, msg in reader.iter_decoded_messages(topics=[topics.RUN_INFO]):
                    return str(msg.data)
    except Exception:  # any trouble: the full reader says what is wrong
        return None
    return None


def _bag_key(bag: Path) -> tuple[str, int, int] | None:
    """What identifies a closed bag's contents (None: no metadata yet, not cached)."""
    try:
        st = (Path(bag) / 'metadata.yaml').stat()
    except OSError:
        return None
    return (str(Path(bag).resolve()), st.st_size, st.st_mtime_ns)


def _legacy(info: dict[str, Any]) -> dict[str, Any]:
    """A bag from before the record (a flat dict with a ``mode``) as this version's JSON."""
    mode = info.get('mode', 'graph')
    hardware = None
    if mode == 'hardware' or 'hardware' in info:
        hardware = {
            'hardware': str(info['hardware']),
            'name': str(info.get('rig') or ''),
            'namespace': str(info.get('namespace') or ''),
            'time_origin': float(info.get('time_origin') or 0.0),
            'truth': info.get('truth'),
            'imagers': info.get('imagers') or {},
        }
    run: dict[str, Any]
    if mode == 'surveil':
        st = info['stream']
        run = {
            'kind': 'session',
            'set_name': info.get('set'),
            'duration': info.get('duration'),
            'stream': {**st, 'script': st.get('script') or ()},
            'demands': info['demands'],
        }
    else:
        run = {
            'kind': 'experiment',
            'set_name': str(info['set']),
            'execution': 'lockstep' if mode == 'lockstep' else 'graph',
            'demand_times': info['demand_times'],
            'faults': info.get('faults') or (),
            'object': info.get('object') or {},
        }
    setup = info.get('setup') if isinstance(info.get('setup'), dict) else None
    obstacles = info.get('obstacles', (setup or {}).get('obstacles')) or ()
    rig = {} if hardware else {k: info.get(k) for k in RigFacts.model_fields}
    return {
        'record': VERSION,
        'run': run,
        'system': str(info['system']),
        'seed': info.get('seed'),
        'predictor': info.get('predictor', 'ca'),
        'marker_radius': float(info.get('marker_radius', 0.0125)),
        'initial_poses': info.get('initial_poses') or {},
        'rig': rig,
        'setup': setup,
        'obstacles': obstacles,
        'hardware': hardware,
        'replayed': mode == 'replay',
        'recorder': info.get('recorder'),
    }
