"""The ``activesurv`` command: experiments, reports, replay, commissioning tools, and the demo.

Every argument is checked (:mod:`activesurv_bringup.arguments`) before any long step. The
modules that run a command (rclpy, OpenCV, matplotlib behind them) are imported in the function
that needs them, so ``--help``, ``--version`` and a refused argument answer at once.

Commands: :data:`EXAMPLES` (the epilog of ``activesurv --help``), a line per typical use;
``activesurv COMMAND --help`` lists every option.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from activesurv_bringup import __version__
from activesurv_bringup.errors import USER_ERRORS, ConfigError, HardwareCheckError
from activesurv_bringup.experiments.options import PROCESSES, RECORD_FRAMES, RunOptions
from activesurv_bringup.files import cache_dir, new_output_dir, timestamped_dir
from activesurv_bringup.rig.parsers import add_hardware_arguments, add_rig_arguments
from activesurv_common.lifetime import STOP_SIGNALS, StopRequested
from activesurv_common.ros import callback_cpu
from activesurv_launch.domains import isolate

if TYPE_CHECKING:  # the checks and the runs load what they need: after --help
    from activesurv_bringup.arguments import Checked
    from activesurv_bringup.experiments.experiment import Experiment

EXAMPLES = """\
  simulate
    activesurv demo --out runs/demo                          # the six experiments and the report
    activesurv experiment --set A --system fast --out runs/a_fast --seed 2 --rtf 2
    activesurv experiment --set B --system medium --out runs/b --mode lockstep
    activesurv experiment --set C --system fast --out runs/c --foxglove
    activesurv experiment --set A --system fast --out runs/f --fault cam2:dead --kill fusion@4:5
    activesurv surveil --out runs/s --duration 120 --objects-at-once 2
  look at a run
    activesurv report runs/a_fast
    activesurv replay runs/a_fast --out runs/a_fast_replay --foxglove
    activesurv bag reindex runs/killed/bag
  simulated rigs and their calibration
    activesurv rig nominal --out rig.yaml
    activesurv rig perturb --in rig.yaml --seed 3 --out rig3.yaml
    activesurv commission --rig rig3.yaml --out cal3
    activesurv experiment --set A --system fast --rig rig3.yaml --calibration cal3 --out runs/r3
  a real rig (or the emulated lab)
    activesurv lab --rig rig.yaml --out lab                  # until Ctrl-C; lab/hardware.yaml
    activesurv lab --rig rig.yaml --out lab2 --controller table=/dev/ttyACM0
    activesurv hardware template --out hw.yaml
    activesurv hardware check hw.yaml
    activesurv stages probe --protocol zaber --port /dev/ttyUSB0
    activesurv commission --live --hardware hw.yaml --out cal --home
    activesurv hardware measure-delay --hardware hw.yaml --calibration cal
    activesurv experiment --hardware hw.yaml --calibration cal --set A --system fast --out runs/hw
    activesurv surveil --hardware hw.yaml --calibration cal --out runs/hw_session
    activesurv stop --hardware hw.yaml                       # e-stop; --release lowers it
"""
"""Typical invocations, by workflow; ``test/test_front_door.py`` parses every line with the
real parser (the text after ``#`` is a comment), so none goes stale."""
SYSTEMS = ('static', 'medium', 'fast')
DEFAULT_SEED = 1
DEFAULT_RIG_SEED = 1


class _Formatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """The usage text as written, and every flag's default in its help (once: a help text
    that says its default in words keeps its own)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ''
        if '(default:' in text:
            return text
        return super()._get_help_string(action)


DDS_PROFILE_HELP = (
    'Fast DDS XML profile for every node of a graph run: large-images (shipped; camera-sized '
    'messages over shared memory without loss) or a path'
)


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='activesurv',
        description='Active-vision multi-camera surveillance (ROS 2 Jazzy).',
        formatter_class=_Formatter,
        epilog='Commands (activesurv COMMAND --help for every option):\n\n' + EXAMPLES,
    )
    parser.add_argument('--version', action='version', version=f'activesurv {__version__}')
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    _experiment_parser(sub)
    _surveil_parser(sub)
    _run_tool_parsers(sub)
    _commission_parser(sub)
    _lab_parser(sub)
    _rig_tool_parsers(sub)
    return parser


def _experiment_parser(sub: Any) -> None:
    """The parser of the experiment command: one of the paper's sets, graph or lockstep."""
    exp = _sub(sub, 'experiment', help="run one of the paper's experiments")
    exp.add_argument(
        '--set',
        dest='set_name',
        required=True,
        choices=('A', 'B', 'C'),
        help="the paper's Set A or B, or ours, C: two objects at once and a post in the cell "
        '(graph mode; docs/multi-object.md)',
    )
    exp.add_argument('--system', required=True, choices=SYSTEMS, help='camera motion class')
    exp.add_argument('--out', type=Path, required=True, help='output directory (new or empty)')
    _add_seed(exp)
    exp.add_argument(
        '--mode',
        choices=('graph', 'lockstep'),
        default='graph',
        help='graph: the node graph over DDS; lockstep: the same cores in one loop',
    )
    exp.add_argument('--trajectory', help='CSV t,x,y replacing the object path')
    exp.add_argument(
        '--predictor',
        choices=('imm', 'ca'),
        default='imm',
        help='imm: manoeuvre-aware (default); ca: the round-1 constant-acceleration filter',
    )
    exp.add_argument('--expect', help='parabolic, diagonal or a CSV: the path placement assumes')
    exp.add_argument(
        '--fault',
        action='append',
        default=[],
        help='CAMERA:KIND[:MAGNITUDE]; kinds: bias, noise, frozen, dead, flip',
    )
    exp.add_argument(
        '--kill',
        action='append',
        default=[],
        help='NODE@T[:RESTART]: SIGKILL a node at simulated time T, restart it at RESTART '
        '(graph mode), e.g. cam2_imager@3.5:6 or fusion@4:5',
    )
    exp.add_argument(
        '--hosts',
        choices=('single', 'netns'),
        default='single',
        help='netns: each camera on its own "host" (network namespace, needs root), over UDP',
    )
    exp.add_argument('--rtf', type=float, default=1.0, help='simulated s per wall s (graph)')
    exp.add_argument(
        '--processes',
        choices=PROCESSES,
        default='containers',
        help='graph mode: nodes grouped into a few container processes per host (default), '
        'or one process per node',
    )
    exp.add_argument('--dds-profile', default=None, help=DDS_PROFILE_HELP)
    exp.add_argument(
        '--image-rate', type=float, default=2.0, help='Hz of overhead images in the bag (0: all)'
    )
    _add_foxglove(exp)
    _add_rig(exp)
    _add_hardware(exp)
    exp.add_argument(
        '--no-motion-correction',
        action='store_true',
        help='free-running cameras: take the nearest frame as it is (to measure what the '
        'correction gains)',
    )
    exp.add_argument(
        '--compose',
        action='store_true',
        help='graph mode with every node in this process (one executor)',
    )


def _surveil_parser(sub: Any) -> None:
    """The parser of the surveil command: continuous surveillance."""
    sv = _sub(
        sub, 'surveil', help='continuous surveillance: objects one after another, until stopped'
    )
    sv.add_argument('--out', type=Path, required=True, help='output directory (new or empty)')
    sv.add_argument('--duration', type=float, default=None, help='simulated s (default: SIGINT)')
    sv.add_argument('--rtf', type=float, default=1.0, help='simulated s per wall s')
    _add_seed(sv)
    sv.add_argument(
        '--arrival-interval', type=float, default=30.0, help='s from one entry to the next'
    )
    sv.add_argument(
        '--demand-interval', type=float, default=2.0, help="s between an object's demands"
    )
    sv.add_argument(
        '--objects-at-once',
        type=int,
        default=1,
        help='objects on the table at once, each in a lane of its own (arrivals overlap: one '
        'every arrival-interval / N s; demands of different objects staggered); 1 to 4',
    )
    sv.add_argument(
        '--demand-at',
        action='append',
        default=[],
        metavar='x=X',
        help='a demand where the object crosses the line x = X m (repeat for more lines); '
        'replaces --demand-interval',
    )
    sv.add_argument(
        '--max-bag-duration', type=float, default=0.0, help='split the bag every S s (0: never)'
    )
    sv.add_argument(
        '--max-bag-size', type=float, default=0.0, help='split the bag every MB (0: never)'
    )
    sv.add_argument(
        '--keep-bags',
        type=int,
        default=0,
        help='keep only the newest N files of the split bag, deleting older ones (0: all)',
    )
    sv.add_argument('--system', choices=SYSTEMS, default='fast', help='camera motion class')
    sv.add_argument(
        '--processes', choices=PROCESSES, default='containers', help='nodes per process'
    )
    sv.add_argument(
        '--image-rate', type=float, default=2.0, help='Hz of overhead images in the bag'
    )
    sv.add_argument('--dds-profile', default=None, help=DDS_PROFILE_HELP)
    _add_foxglove(sv)
    _add_rig(sv)
    _add_hardware(sv)


def _run_tool_parsers(sub: Any) -> None:
    """The parser of replay, report and demo."""
    rpl = _sub(sub, 'replay', help='re-run imaging and fusion on a recorded run')
    rpl.add_argument('bag', type=Path, help='a recorded run: its bag, or the run directory')
    rpl.add_argument('--out', type=Path, required=True, help='output directory (new or empty)')
    rpl.add_argument('--rtf', type=float, default=1.0, help='bag s per wall s')
    _add_foxglove(rpl)

    rep = _sub(sub, 'report', help='plots and report.md from recorded runs')
    rep.add_argument('path', type=Path, help='a run directory, a bag, or a directory of runs')
    rep.add_argument(
        '--out',
        type=Path,
        default=None,
        help='where report.md and the plots go (default: next to the runs; results.json of '
        'the runs are never rewritten)',
    )

    demo = _sub(sub, 'demo', help='the main job: all six experiments and the report')
    demo.add_argument(
        '--out',
        type=Path,
        default=None,
        help='output directory (new or empty); default: a new runs/demo_<date-time>',
    )
    _add_seed(demo)
    demo.add_argument(
        '--mode', choices=('graph', 'lockstep'), default='graph', help='graph or lockstep'
    )
    demo.add_argument('--rtf', type=float, default=1.0, help='simulated s per wall s')
    demo.add_argument(
        '--processes', choices=PROCESSES, default='containers', help='nodes per process'
    )
    demo.add_argument('--dds-profile', default=None, help=DDS_PROFILE_HELP)
    _add_rig(demo)


def _commission_parser(sub: Any) -> None:
    """The parser of the commission command."""
    com = _sub(
        sub,
        'commission',
        help='calibrate a rig through the node graph (cameras, mounts, overhead)',
    )
    com.add_argument('--rig', type=Path, default=None, help='rig YAML to simulate')
    com.add_argument('--out', type=Path, required=True, help='calibration directory (new)')
    com.add_argument(
        '--live',
        action='store_true',
        help='commission the stages, table and cameras running on this ROS domain',
    )
    com.add_argument(
        '--cameras', default=None, help='comma-separated dynamic cameras (default: all)'
    )
    com.add_argument(
        '--hardware',
        type=Path,
        default=None,
        help="with --live: the rig's hardware file; its stage bridges (homing) and camera "
        'drivers are started, its camera topics listened to',
    )
    com.add_argument(
        '--home',
        action='store_true',
        help="with --hardware: home unreferenced axes when the bridges connect (or the file's "
        'home: true); never otherwise',
    )
    _add_yes(com)
    com.add_argument(
        '--stations',
        type=int,
        default=None,
        help='at most this many stage stations per camera, spread over the procedure '
        '(a quick check after a bump: fewer board views, larger uncertainties in '
        'commission.json) (default: all, 16 or so per camera)',
    )


def _lab_parser(sub: Any) -> None:
    """The parser of the lab command: an emulated lab."""
    lab = _sub(
        sub,
        'lab',
        help='an emulated lab (serial controllers, bridges, cameras) for commission --live',
    )
    lab.add_argument('--rig', type=Path, required=True, help='rig YAML the cameras simulate')
    lab.add_argument('--out', type=Path, required=True, help='directory for ports, logs (new)')
    lab.add_argument(
        '--cameras', default=None, help='comma-separated dynamic cameras (default: all)'
    )
    lab.add_argument(
        '--controller',
        action='append',
        default=[],
        metavar='NAME=PORT',
        help='an external controller in place of an emulated one (NAME: table or a camera id)',
    )
    lab.add_argument(
        '--frame-rate', type=float, default=30.0, help="Hz the lab's cameras free-run at"
    )
    lab.add_argument('--namespace', default='', help="ROS namespace of the lab's rig")
    lab.add_argument(
        '--exposure-delay',
        action='append',
        default=[],
        metavar='NAME=S',
        help="a lab camera's true exposure delay (s; default 0.02, what the lab's hardware file "
        'says): what activesurv hardware measure-delay must find',
    )
    lab.add_argument(
        '--trigger',
        choices=('free', 'software'),
        default='free',
        help='the dynamic cameras: free-running, or software-triggered (each exposes when its '
        '<cam>_camera/trigger service is called; the hardware file says so)',
    )
    lab.add_argument(
        '--clock-offset',
        action='append',
        default=[],
        metavar='NAME=S',
        help="a lab camera's clock ahead of the host's (s): its stamps are off by it",
    )


def _rig_tool_parsers(sub: Any) -> None:
    """The parser of stop, hardware, rig, bag and stages."""
    stop = _sub(
        sub,
        'stop',
        help="raise the rig's e-stop (every stage bridge stops its axes and refuses goals) "
        'and wait for every bridge to confirm; --release lowers it',
    )
    stop.add_argument('--hardware', type=Path, required=True, help="the rig's hardware file")
    stop.add_argument('--release', action='store_true', help='lower the e-stop instead')
    stop.add_argument(
        '--timeout', type=float, default=10.0, help='s to wait for every bridge to confirm'
    )

    hw = _sub(sub, 'hardware', help='hardware files: a real rig (template, check)')
    add_hardware_arguments(hw.add_subparsers(dest='hardware_command', required=True))

    rig = _sub(sub, 'rig', help='rig files: the simulated hardware (nominal, perturb)')

    add_rig_arguments(rig.add_subparsers(dest='rig_command', required=True))

    bag = _sub(sub, 'bag', help='bag tools (reindex a bag whose recorder was killed)')
    bag_sub = bag.add_subparsers(dest='bag_command', required=True)
    rix = _sub(
        bag_sub,
        'reindex',
        help='rebuild index and metadata.yaml; the original goes to BAG.damaged',
    )
    rix.add_argument('bag', type=Path, help='the bag directory')

    stages = _sub(sub, 'stages', help='commissioning of stage controllers (probe, move)')
    from activesurv_stages.cli import add_arguments

    add_arguments(stages.add_subparsers(dest='stages_command', required=True))


def _add_foxglove(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--foxglove',
        type=int,
        nargs='?',
        const=8765,
        default=None,
        metavar='PORT',
        help='serve the run live over the Foxglove WebSocket protocol (default port 8765)',
    )


def _sub(sub: Any, name: str, **kwargs: Any) -> argparse.ArgumentParser:
    """A sub-command whose help shows every flag's default."""
    parser: argparse.ArgumentParser = sub.add_parser(name, formatter_class=_Formatter, **kwargs)
    return parser


def _add_seed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--seed',
        type=int,
        default=DEFAULT_SEED,
        help="seeds the run (paths, image noise); the rig is --rig-seed's",
    )


def _add_hardware(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--hardware',
        type=Path,
        default=None,
        help='run on the real rig this hardware file describes (wall clock; see '
        'activesurv hardware template) instead of the simulator',
    )
    parser.add_argument(
        '--home',
        action='store_true',
        help="with --hardware: home unreferenced axes when the bridges connect (or the file's "
        'home: true); never otherwise',
    )
    _add_yes(parser)
    parser.add_argument(
        '--record-frames',
        choices=RECORD_FRAMES,
        default='used',
        help="with --hardware: the dynamic cameras' frames in the bag: used (each frame an "
        'imager measured for a demand, PNG: look at and replay a failed demand), all, none',
    )


def _add_yes(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--yes',
        action='store_true',
        help='with --hardware: move without asking (the plan is listed and a question asked '
        'first otherwise; without a terminal a hardware run needs --yes)',
    )


def _add_rig(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        '--rig',
        type=Path,
        default=None,
        help='rig YAML: the simulated hardware (default: the nominal rig perturbed with '
        '--rig-seed)',
    )
    parser.add_argument(
        '--rig-seed',
        type=int,
        default=DEFAULT_RIG_SEED,
        help='which perturbed rig to simulate when --rig is not given (independent of --seed)',
    )
    parser.add_argument(
        '--calibration',
        default=None,
        metavar='{CALDIR,nominal,truth}',
        help='what the system is told about the rig: a calibration directory, the nominal '
        'values, or the rig itself (default: the rig commissioned once, cached per rig in '
        f'{cache_dir() / "calibrations"})',
    )


def experiment(
    set_name: str,
    system: str,
    out: Path,
    *,
    seed: int = DEFAULT_SEED,
    mode: str = 'graph',
    trajectory: str | None = None,
    expect: str | None = None,
    options: RunOptions | None = None,
    predictor: str = 'imm',
    rig: Path | None = None,
    calibration: str | None = None,
    rig_seed: int = DEFAULT_RIG_SEED,
    hardware: Path | None = None,
    home: bool = False,
    motion_correction: bool = True,
) -> dict[str, Any]:
    """Run one experiment into ``out`` (new or empty); returns its results document.

    With ``hardware`` it runs on that rig (its calibration: ``calibration``, else the hardware
    file's), on the wall clock; otherwise on the simulator playing ``rig`` (lockstep or the
    node graph, by ``mode``).

    Raises:
        ConfigError: for a bad configuration; NodeDiedError if a node of the graph dies.
    """
    from activesurv_bringup.experiments.experiment import load_experiment
    from activesurv_bringup.experiments.scenes import SCENES
    from activesurv_bringup.rig.choice import choose

    opts = options or RunOptions()
    if opts.kills and mode != 'graph':
        raise ConfigError('--kill needs --mode graph (lockstep has no processes to kill)')

    def say(text: str) -> None:
        print(f'  Set {set_name} {system}: {text}', flush=True)

    new_output_dir(out)  # refused before anything is commissioned or run
    started = time.monotonic()
    if hardware is not None:
        doc = _experiment_on_rig(
            set_name, system, out, seed, trajectory, expect, predictor, opts, hardware,
            calibration, home, motion_correction, say,
        )  # fmt: skip
    else:
        choice = choose(rig, calibration, rig_seed, cache_dir(), say, _commission)
        if set_name in SCENES:
            return _scene(set_name, system, out, seed, choice, opts, say)
        exp = load_experiment(set_name, system, seed, trajectory, expect, rig=choice)
        doc = _simulated(exp.with_predictor(predictor), out, mode, opts, say)
    say(f'done in {time.monotonic() - started:.1f} s -> {out / "results.json"}')
    return doc


def _experiment_on_rig(
    set_name: str,
    system: str,
    out: Path,
    seed: int,
    trajectory: str | None,
    expect: str | None,
    predictor: str,
    opts: RunOptions,
    hardware: Path,
    calibration: str | None,
    home: bool,
    motion_correction: bool,
    say: Callable[[str], None],
) -> dict[str, Any]:
    """An experiment on the rig of the hardware file ``hardware`` (its measured delays)."""
    from activesurv_bringup.experiments.experiment import load_experiment
    from activesurv_bringup.experiments.hardware_graph import run_hardware
    from activesurv_bringup.rig.hardware import calibration_dir, hardware_choice, read
    from activesurv_evaluation.runs import finish_run
    from activesurv_hardware.delays import with_measured_delays

    hw = read(hardware)
    choice = hardware_choice(hw, calibration)
    hw = with_measured_delays(hw, calibration_dir(hw, calibration), say)
    exp = load_experiment(set_name, system, seed, trajectory, expect, rig=choice)
    _preload_evaluation()
    with results_on_stop(out):
        run_hardware(
            exp.with_predictor(predictor), hw, out, opts, say, home or hw.home, motion_correction
        )
    return finish_run(out)


def _commission(out: Path, rig: Any, **kwargs: Any) -> Any:
    """Commissions a rig for a run without a calibration (its modules loaded only then)."""
    from activesurv_bringup.rig.commission import run_commission

    return run_commission(out, rig, **kwargs)


def _simulated(
    exp: Experiment, out: Path, mode: str, opts: RunOptions, say: Callable[[str], None]
) -> dict[str, Any]:
    """A simulated experiment: lockstep, the node graph, or the graph over network namespaces.
    The evaluation's modules (stonesoup, scipy.optimize: 0.4 s) are imported after a graph
    run, not before its start."""
    if mode == 'lockstep':
        from activesurv_bringup.experiments.lockstep import run_lockstep
        from activesurv_evaluation.runs import finish_run
        from activesurv_evaluation.tracking import track_metrics

        def progress(j: int, m: int, t: float) -> None:
            say(f'demand {j} of {m}, simulated time {t:.1f} s')

        track_log: list[Any] = []
        records = run_lockstep(exp, opts.faults, progress, track_log=track_log)
        return finish_run(
            out,
            record=exp.record(opts.faults, execution='lockstep'),
            demands=records,
            tracking=track_metrics([m for m, _ in track_log], [t for _, t in track_log]),
        )
    if opts.hosts == 'netns':
        return _run_on_hosts(exp, out, opts, say)
    from activesurv_bringup.experiments.graph import run_graph

    if opts.dds_profile is not None:
        say(f'Fast DDS profile {opts.dds_profile}')
    _preload_evaluation()
    with results_on_stop(out):
        run_graph(exp, out, opts, progress=say)
    from activesurv_evaluation.runs import finish_run

    doc = finish_run(out)
    if callback_cpu.enabled():  # the processes traced their calls: what ran at an instant
        from activesurv_evaluation.timeline import write_timeline

        png = write_timeline(out, len(os.sched_getaffinity(0)), opts.rtf)  # as make bench
        if png is not None:
            say(f'what ran around the median demand: {png} (every demand: timeline.json)')
    return doc


def _preload_evaluation() -> None:
    """Import the evaluation a run ends with in a daemon thread, while the graph starts (the
    orchestrator waits for its nodes then): scipy.optimize and Stone Soup cost 1.1 s of a 2-core
    host at the end, and a run stopped by SIGTERM has 10 s to write its results and leave."""

    def load() -> None:
        with contextlib.suppress(Exception):  # the evaluation reports its errors when it runs
            import stonesoup.measures
            import stonesoup.metricgenerator.ospametric  # noqa: F401

            import activesurv_evaluation.runs  # noqa: F401

    threading.Thread(target=load, name='preload-evaluation', daemon=True).start()


@contextlib.contextmanager
def results_on_stop(out: Path) -> Iterator[None]:
    """A run stopped by a signal still writes ``results.json`` for the demands so far (its bag
    is closed), then the stop goes on up (a demo does not start its next run)."""
    try:
        yield
    except StopRequested:
        from activesurv_evaluation.runs import finish_run  # evaluation: lazy, as above

        if (out / 'bag' / 'metadata.yaml').is_file():
            finish_run(out, partial=True)
        raise


def measure_delay(args: argparse.Namespace) -> list[str]:
    """``activesurv hardware measure-delay``: the cameras' delays into CALDIR/delays.yaml."""
    # The ROS graph and rclpy only for this subcommand (check and template stay light).
    from activesurv_bringup.rig.delays import run_measure_delay
    from activesurv_bringup.rig.hardware import read

    hw = read(args.hardware)
    cams = [c.strip() for c in args.cameras.split(',')] if args.cameras else None
    fits = run_measure_delay(
        hw,
        Path(args.calibration),
        cams,
        args.home or hw.home,
        progress=lambda text: print(f'  measure-delay: {text}', flush=True),
    )
    return [
        f'{cid}: exposure_delay {1e3 * f.delay:.1f} ms (file: '
        f'{1e3 * hw.cameras.get(cid, hw.overhead).exposure_delay:.1f} ms), jitter '
        f'{1e3 * f.jitter:.1f} ms, {f.samples} frames'
        for cid, f in fits.items()
    ]


def _scene(
    set_name: str,
    system: str,
    out: Path,
    seed: int,
    choice: Any,
    opts: RunOptions,
    say: Callable[[str], None],
) -> dict[str, Any]:
    """A named set of our own (``C``): its scripted objects and obstacles, run as a short
    surveillance session on the run's rig (the same graph, results and report)."""
    from activesurv_bringup.experiments.scenes import load_scene
    from activesurv_bringup.experiments.session_options import SurveilOptions
    from activesurv_bringup.experiments.surveil import run_surveil
    from activesurv_evaluation.session_report import session_table

    scene = load_scene(set_name)
    session = SurveilOptions(
        duration=scene.duration,
        demand_interval=scene.demand_interval,
        system=system,
        seed=seed,
        rig=scene.on(choice),
        objects_at_once=scene.lanes,
        script=scene.objects,
        set_name=set_name,
    )
    say(
        f'{scene.description}: {len(scene.objects)} objects, {len(scene.obstacles)} obstacles, '
        f'{scene.duration:.0f} s'
    )
    started = time.monotonic()
    _preload_evaluation()
    doc = run_surveil(out, session, opts, say)
    print(session_table(doc), flush=True)
    say(f'done in {time.monotonic() - started:.1f} s -> {out / "results.json"}')
    return doc


def _run_on_hosts(
    exp: Any, out: Path, opts: RunOptions, say: Callable[[str], None]
) -> dict[str, Any]:
    """Run the graph over network namespaces: core plus one host per camera, DDS over UDP."""
    from activesurv_bringup.experiments.graph import run_graph
    from activesurv_evaluation.runs import finish_run
    from activesurv_launch.netns import NetnsHosts, unavailable_reason

    reason = unavailable_reason()
    if reason is not None:
        raise ConfigError(f'--hosts netns: network namespaces cannot be made here: {reason}')
    cameras = [s.camera_id for s in exp.setup.sensors]
    with NetnsHosts(['core', *cameras]) as hosts:
        hosts.enter('core')
        say(f'hosts: {hosts.addresses}')
        run_graph(exp, out, opts, progress=say, hosts=hosts)
        traffic = hosts.traffic_bytes()
    doc = finish_run(
        out,
        extra={'hosts': {'mode': 'netns', 'addresses': hosts.addresses, 'traffic_bytes': traffic}},
    )
    say(f'bytes through each host interface: {traffic}')
    return doc


def surveil(
    out: Path,
    session: Any,
    options: RunOptions | None = None,
    hardware: Any = None,
    home: bool = False,
) -> dict[str, Any]:
    """Run a continuous session into ``out`` (new or empty); returns its results document
    (with ``hardware``, a :class:`~activesurv_hardware.hardware_file.Hardware`, on that rig)."""
    from activesurv_bringup.experiments.surveil import run_surveil

    new_output_dir(out)
    started = time.monotonic()

    def say(text: str) -> None:
        print(f'  surveil: {text}', flush=True)

    home = home or (hardware is not None and hardware.home)
    _preload_evaluation()
    doc = run_surveil(out, session, options, say, hardware, home)
    s = doc['summary']
    lat = s['latency_median_ms']
    say(
        f'{s["objects"]} objects, {s["demands"]} demands, {s["ok"]} ok, median latency '
        + (f'{lat:.0f} ms' if lat is not None else '-')
        + f'; {time.monotonic() - started:.0f} s -> {out / "results.json"}'
    )
    return doc


def replay(
    bag: Path, out: Path, rtf: float = 1.0, foxglove: int | None = None
) -> list[dict[str, Any]]:
    """Re-run imaging and fusion on a recorded run (its bag or its directory) into ``out``."""
    from activesurv_bringup.experiments.replay import compare, run_replay

    if not (bag / 'metadata.yaml').exists() and (bag / 'bag').is_dir():
        bag = bag / 'bag'  # a run directory
    new_output_dir(out)
    new = run_replay(bag, out, rtf, foxglove=foxglove)
    rows = compare(bag, new)
    (out / 'replay.json').write_text(json.dumps(rows, indent=2))
    print(f'{"demand":>6} {"recorded":>9} {"replayed":>9} {"difference [mm]":>16}')
    for r in rows:
        d = r['position_difference']
        print(
            f'{r["index"]:>6} {r["recorded_status"]!s:>9} '
            f'{r["replayed_status"]!s:>9} {1e3 * d:16.6f}'
        )
    print(f'\nreplayed bag: {new}')
    return rows


def _camera_list(cameras: str | None) -> list[str] | None:
    return [c.strip() for c in cameras.split(',') if c.strip()] if cameras else None


def commission(
    out: Path,
    rig: Path | None,
    live: bool = False,
    cameras: str | None = None,
    hardware: Path | None = None,
    stations: int | None = None,
    home: bool = False,
) -> dict[str, Any]:
    """``activesurv commission``: calibrate a simulated rig (``rig``) or the live one (with
    ``hardware``, the rig that hardware file describes)."""
    from activesurv_bringup.rig.commission import run_commission
    from activesurv_bringup.rig.hardware import read
    from activesurv_bringup.rig.rigs import resolve_rig

    if (rig is None) == (not live):
        raise ConfigError('give --rig RIG.yaml (simulation) or --live (the running hardware)')
    the_rig = resolve_rig(rig, 0)[0] if rig is not None else None
    hw = read(hardware) if hardware is not None else None
    chosen = _camera_list(cameras) or (list(hw.cameras) if hw is not None else None)

    def say(text: str) -> None:
        print(f'  commission: {text}', flush=True)

    doc = run_commission(out, the_rig, chosen, say, hardware=hw, stations=stations, home=home)
    say(f'done in {doc["seconds"]:.0f} s -> {out}')
    return doc


def report(path: Path, out: Path | None = None) -> Path:
    """Plots and report.md of recorded runs (into ``out``); returns the report's path."""
    from activesurv_evaluation.report import report as make_report
    from activesurv_evaluation.report import summary_table

    docs, out = make_report(path, out)
    if docs and all(d.get('mode') == 'surveil' for d in docs):
        from activesurv_evaluation.session_report import session_table

        print('\n\n'.join(session_table(d) for d in docs))
    else:
        print(summary_table(docs))
    print(f'\nreport: {out}')
    return out


def demo(
    out: Path | None,
    seed: int = DEFAULT_SEED,
    mode: str = 'graph',
    options: RunOptions | None = None,
    rig: Path | None = None,
    calibration: str | None = None,
    rig_seed: int = DEFAULT_RIG_SEED,
) -> Path:
    """The six experiments and their report, in a new directory; returns it."""
    from activesurv_evaluation.report import summary_table, write_report

    root = new_output_dir(out) if out is not None else timestamped_dir(Path('runs'), 'demo')
    print(f'activesurv demo: writing to {root}', flush=True)
    docs = []
    started = time.monotonic()
    for set_name in ('A', 'B'):
        for system in SYSTEMS:
            print(f'activesurv demo: Set {set_name}, {system} system ({mode})', flush=True)
            docs.append(
                experiment(
                    set_name,
                    system,
                    root / f'{set_name}_{system}',
                    seed=seed,
                    mode=mode,
                    options=options,
                    rig=rig,
                    calibration=calibration,
                    rig_seed=rig_seed,
                )
            )
    path = write_report(docs, root)
    print(f'\nactivesurv demo: six runs in {time.monotonic() - started:.0f} s\n')
    print(summary_table(docs))
    print(f'\nreport: {path}\nresults: {root}/*/results.json')
    (root / 'demo.json').write_text(
        json.dumps({'seconds': time.monotonic() - started, 'mode': mode}, indent=2)
    )
    return root


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    if args.command == 'stages':
        from activesurv_stages.cli import run

        return run(args)
    out = getattr(args, 'out', None)
    made = out is not None and not Path(out).exists()
    # SIGTERM and SIGHUP (systemd, docker stop, timeout, a closed terminal) are SIGINT: a graph
    # run stops cleanly (results.json, bag closed); any other step unwinds through its finally.
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.default_int_handler)
    try:
        from activesurv_bringup import arguments  # the checks load what they check: after --help

        checked = arguments.check(args)
        if simulated(args):
            claim = isolate(os.environ)
            if not claim.chosen_by_user:
                print(
                    f'activesurv {args.command}: simulated run on ROS domain {claim.domain_id} '
                    '(a free one, localhost discovery; set ROS_DOMAIN_ID to choose)',
                    flush=True,
                )
        _dispatch(args, checked)
    except HardwareCheckError as exc:
        if args.command != 'hardware' or not getattr(args, 'file', None):
            print(f'activesurv {args.command}: error: {exc}', file=sys.stderr)
            return 1
        # hardware check: one line per mistake, each naming the file and the key path.
        for line in exc.problems:
            print(f'{args.file}: {line}', file=sys.stderr)
        return 2
    except USER_ERRORS + (OSError, ValueError) as exc:
        print(f'activesurv {args.command}: error: {exc}', file=sys.stderr)
        return 1
    except StopRequested as exc:
        print(
            f'activesurv {args.command}: stopped by {exc.signal_name}; what ran is written '
            f'(results.json, bag closed)',
            file=sys.stderr,
        )
        return exc.exit_status
    except KeyboardInterrupt:  # a second Ctrl-C while stopping: the nodes were still stopped
        print(f'activesurv {args.command}: interrupted', file=sys.stderr)
        return 130
    finally:
        if made and out is not None:
            _drop_if_empty(Path(out))
    return 0


def simulated(args: argparse.Namespace) -> bool:
    """Whether the command runs the simulator (and so must not share a real rig's domain)."""
    if args.command == 'commission':
        return not args.live
    if getattr(args, 'hardware', None) is not None:
        return False  # the rig's own domain, as its drivers use
    return args.command in ('experiment', 'surveil', 'demo', 'replay')


def _drop_if_empty(out: Path) -> None:
    """A failed command leaves no empty ``--out`` it made (never one holding anything)."""
    try:
        if out.is_dir() and not any(out.iterdir()):
            out.rmdir()
    except OSError:
        pass


def _dispatch(args: argparse.Namespace, checked: Checked) -> None:
    if getattr(args, 'hardware', None) is not None and args.command != 'stop':
        from activesurv_bringup.rig.hardware import confirm_motion, read, rig_ports
        from activesurv_hardware.rig_lock import RigLock

        rig_file = read(args.hardware)
        what = args.hardware_command if args.command == 'hardware' else args.command
        # One run at a time on a rig: its controller ports stay locked for this process's life.
        with RigLock(rig_ports(rig_file), f'activesurv {what} --hardware {args.hardware}'):
            confirm_motion(rig_file, what, args.yes, args.home or rig_file.home)
            COMMANDS[args.command](args, checked)
        return
    COMMANDS[args.command](args, checked)


def _experiment_command(args: argparse.Namespace, checked: Checked) -> None:
    experiment(
        args.set_name,
        args.system,
        args.out,
        seed=args.seed,
        mode=args.mode,
        trajectory=args.trajectory,
        expect=args.expect,
        options=checked.run,
        predictor=args.predictor,
        rig=args.rig,
        calibration=args.calibration,
        rig_seed=args.rig_seed,
        hardware=args.hardware,
        home=args.home,
        motion_correction=not args.no_motion_correction,
    )


def _surveil_command(args: argparse.Namespace, checked: Checked) -> None:
    from activesurv_bringup.rig.choice import choose

    new_output_dir(args.out)  # refused before anything is commissioned

    def say(text: str) -> None:
        print(f'  surveil: {text}', flush=True)

    hw = None
    if args.hardware is not None:
        from activesurv_bringup.rig.hardware import calibration_dir, hardware_choice, read
        from activesurv_hardware.delays import with_measured_delays

        hw = read(args.hardware)
        rig = hardware_choice(hw, args.calibration)
        hw = with_measured_delays(hw, calibration_dir(hw, args.calibration), say)
    else:
        rig = choose(args.rig, args.calibration, args.rig_seed, cache_dir(), say, _commission)
    assert checked.surveil is not None  # built by the checks of a surveil command line
    surveil(args.out, replace(checked.surveil, rig=rig), checked.run, hw, args.home)


def _bag_command(args: argparse.Namespace, checked: Checked) -> None:
    from activesurv_recording.salvage import reindex

    print(json.dumps(reindex(args.bag).as_dict(), indent=2))


def _lab_command(args: argparse.Namespace, checked: Checked) -> None:
    from activesurv_bringup.rig.lab import run_lab

    run_lab(
        args.rig,
        args.out,
        _camera_list(args.cameras),
        controllers=dict(checked.controllers),
        frame_rate=args.frame_rate,
        namespace=args.namespace,
        delays=dict(checked.delays),
        offsets=dict(checked.offsets),
        trigger=args.trigger,
    )


def _stop_command(args: argparse.Namespace, checked: Checked) -> None:
    from activesurv_bringup.rig.hardware import read
    from activesurv_hardware.ros.estop import run_stop  # rclpy: only this command needs it

    run_stop(
        read(args.hardware),
        args.release,
        args.timeout,
        lambda text: print(f'activesurv stop: {text}', flush=True),
    )


def _hardware_command(args: argparse.Namespace, checked: Checked) -> None:
    if args.hardware_command == 'measure-delay':
        print('\n'.join(measure_delay(args)))
    else:
        from activesurv_bringup.rig.hardware import run as run_hardware_command

        print('\n'.join(run_hardware_command(args)))


def _rig_command(args: argparse.Namespace, checked: Checked) -> None:
    from activesurv_bringup.rig.rigs import run as write_rig

    print(f'rig written: {write_rig(args)}')


# What each command runs (its arguments were checked before: arguments.check).
COMMANDS: dict[str, Callable[[argparse.Namespace, Checked], object]] = {
    'experiment': _experiment_command,
    'surveil': _surveil_command,
    'replay': lambda a, _: replay(a.bag, a.out, a.rtf, a.foxglove),
    'bag': _bag_command,
    'report': lambda a, _: report(a.path, a.out),
    'demo': lambda a, c: demo(a.out, a.seed, a.mode, c.run, a.rig, a.calibration, a.rig_seed),
    'commission': lambda a, _: commission(
        a.out, a.rig, a.live, a.cameras, a.hardware, a.stations, a.home
    ),
    'lab': _lab_command,
    'stop': _stop_command,
    'hardware': _hardware_command,
    'rig': _rig_command,
}

if __name__ == '__main__':
    sys.exit(main())
