"""The ``activesurv`` command: experiments, reports, replay, commissioning tools, and the demo.

::

    activesurv experiment --set {A,B} --system {static,medium,fast} --out DIR [--seed N]
        [--mode {graph,lockstep}] [--trajectory PATH.csv] [--expect {parabolic,diagonal,PATH.csv}]
        [--fault CAMERA:KIND[:MAGNITUDE] ...] [--kill NODE@T[:RESTART] ...]
        [--rtf X] [--image-rate HZ] [--compose] [--hosts {single,netns}]
        [--dds-profile {large-images,PATH.xml}]
    activesurv report RUN_DIR_OR_BAG
    activesurv replay RUN_DIR_OR_BAG --out DIR [--rtf X]
    activesurv demo [--out DIR] [--mode {graph,lockstep}]
    activesurv bag reindex BAG
    activesurv stages {probe,move,emulate} ...
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from activesurv_bringup.errors import BringupError

SYSTEMS = ('static', 'medium', 'fast')
DDS_PROFILE_HELP = (
    'Fast DDS XML profile for every node of a graph run: large-images (shipped; camera-sized '
    'messages over shared memory without loss) or a path'
)


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='activesurv',
        description='Active-vision multi-camera surveillance (ROS 2 Jazzy).',
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__,
    )
    sub = parser.add_subparsers(dest='command', required=True)

    exp = sub.add_parser('experiment', help="run one of the paper's experiments")
    exp.add_argument('--set', dest='set_name', required=True, choices=('A', 'B'))
    exp.add_argument('--system', required=True, choices=SYSTEMS)
    exp.add_argument('--out', type=Path, required=True, help='output directory')
    exp.add_argument('--seed', type=int, default=0)
    exp.add_argument('--mode', choices=('graph', 'lockstep'), default='graph')
    exp.add_argument('--trajectory', help='CSV t,x,y replacing the object path')
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
    exp.add_argument('--rtf', type=float, default=0.5, help='simulated s per wall s (graph)')
    exp.add_argument('--dds-profile', default=None, help=DDS_PROFILE_HELP)
    exp.add_argument(
        '--image-rate', type=float, default=2.0, help='Hz of overhead images in the bag (0: all)'
    )
    exp.add_argument(
        '--compose',
        action='store_true',
        help='graph mode with every node in this process (one executor)',
    )

    rpl = sub.add_parser('replay', help='re-run imaging and fusion on a recorded run')
    rpl.add_argument('bag', type=Path, help='a recorded run: its bag, or the run directory')
    rpl.add_argument('--out', type=Path, required=True, help='output directory')
    rpl.add_argument('--rtf', type=float, default=0.5, help='bag s per wall s')

    rep = sub.add_parser('report', help='results.json, plots and report from recorded runs')
    rep.add_argument('path', type=Path, help='a run directory, a bag, or a directory of runs')

    demo = sub.add_parser('demo', help='the main job: all six experiments and the report')
    demo.add_argument('--out', type=Path, default=Path('runs/demo'), help='output directory')
    demo.add_argument('--seed', type=int, default=1)
    demo.add_argument('--mode', choices=('graph', 'lockstep'), default='graph')
    demo.add_argument('--rtf', type=float, default=0.5)
    demo.add_argument('--dds-profile', default=None, help=DDS_PROFILE_HELP)

    bag = sub.add_parser('bag', help='bag tools (reindex a bag whose recorder was killed)')
    bag_sub = bag.add_subparsers(dest='bag_command', required=True)
    rix = bag_sub.add_parser(
        'reindex', help='rebuild index and metadata.yaml; the original goes to BAG.damaged'
    )
    rix.add_argument('bag', type=Path)

    stages = sub.add_parser('stages', help='commissioning of stage controllers (probe, move)')
    from activesurv_stages.cli import add_arguments

    add_arguments(stages.add_subparsers(dest='stages_command', required=True))
    return parser


def run_experiment(
    args: argparse.Namespace, out: Path, set_name: str, system: str, seed: int
) -> dict[str, object]:
    from activesurv_bringup.evaluation import results_document, write_results
    from activesurv_bringup.experiment import load_experiment
    from activesurv_bringup.faults import parse_fault, parse_kill

    faults = [parse_fault(f) for f in getattr(args, 'fault', [])]
    kills = [parse_kill(k) for k in getattr(args, 'kill', [])]
    if kills and args.mode != 'graph':
        from activesurv_bringup.errors import ConfigError

        raise ConfigError('--kill needs --mode graph (lockstep has no processes to kill)')
    exp = load_experiment(
        set_name, system, seed, getattr(args, 'trajectory', None), getattr(args, 'expect', None)
    )
    started = time.monotonic()
    if args.mode == 'lockstep':
        from activesurv_bringup.lockstep import run_lockstep

        def progress(j: int, m: int, t: float) -> None:
            print(
                f'  Set {set_name} {system}: demand {j} of {m}, simulated time {t:.1f} s',
                flush=True,
            )

        records = run_lockstep(exp, faults, progress)
        doc = results_document(
            set_name,
            system,
            records,
            {
                'seed': seed,
                'mode': 'lockstep',
                'faults': [f'{f.camera}:{f.kind}:{f.magnitude:g}' for f in faults],
            },
        )
        write_results(out / 'results.json', doc)
    else:
        from activesurv_bringup.graph import run_graph
        from activesurv_bringup.report import load_run

        def say(text: str) -> None:
            print(f'  Set {set_name} {system}: {text}', flush=True)

        profile = getattr(args, 'dds_profile', None)
        if profile:
            from activesurv_bringup.errors import ConfigError
            from activesurv_bringup.experiment import dds_profile_path

            if getattr(args, 'hosts', 'single') == 'netns':
                raise ConfigError('--dds-profile and --hosts netns do not mix (hosts use UDPv4)')
            path = dds_profile_path(profile)
            os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(path)  # every node inherits it
            say(f'Fast DDS profile {path}')

        def graph(hosts: Any = None) -> None:
            run_graph(
                exp,
                out,
                rtf=args.rtf,
                image_rate=getattr(args, 'image_rate', 2.0),
                faults=faults,
                progress=say,
                compose=getattr(args, 'compose', False),
                kills=kills,
                hosts=hosts,
            )

        if getattr(args, 'hosts', 'single') == 'netns':
            doc = _run_on_hosts(exp, out, graph, say)
        else:
            graph()
            doc = load_run(out)
    print(
        f'  Set {set_name} {system}: done in {time.monotonic() - started:.1f} s -> '
        f'{out / "results.json"}',
        flush=True,
    )
    return doc


def _run_on_hosts(
    exp: Any, out: Path, graph: Callable[[Any], None], say: Callable[[str], None]
) -> dict[str, Any]:
    """Run the graph over network namespaces: core plus one host per camera, DDS over UDP."""
    from activesurv_bringup.errors import ConfigError
    from activesurv_bringup.evaluation import write_results
    from activesurv_bringup.netns import NetnsHosts, unavailable_reason
    from activesurv_bringup.report import load_run

    reason = unavailable_reason()
    if reason is not None:
        raise ConfigError(f'--hosts netns: network namespaces cannot be made here: {reason}')
    cameras = [s.camera_id for s in exp.setup.sensors]
    with NetnsHosts(['core', *cameras]) as hosts:
        # Discovery over the bridge (multicast on the subnet); no shared memory between hosts.
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SUBNET'
        os.environ['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
        hosts.enter('core')
        say(f'hosts: {hosts.addresses}')
        graph(hosts)
        traffic = hosts.traffic_bytes()
    doc = load_run(out)
    doc['hosts'] = {'mode': 'netns', 'addresses': hosts.addresses, 'traffic_bytes': traffic}
    write_results(out / 'results.json', doc)
    say(f'bytes through each host interface: {traffic}')
    return doc


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    if args.command == 'stages':
        from activesurv_stages.cli import run

        return run(args)
    try:
        if args.command == 'experiment':
            run_experiment(args, args.out, args.set_name, args.system, args.seed)
            return 0
        if args.command == 'replay':
            from activesurv_bringup.replay import compare, run_replay

            if not (args.bag / 'metadata.yaml').exists() and (args.bag / 'bag').is_dir():
                args.bag = args.bag / 'bag'  # a run directory
            new = run_replay(args.bag, args.out, args.rtf)
            rows = compare(args.bag, new)
            (args.out / 'replay.json').write_text(json.dumps(rows, indent=2))
            print(f'{"demand":>6} {"recorded":>9} {"replayed":>9} {"difference [mm]":>16}')
            for r in rows:
                d = r['position_difference']
                print(
                    f'{r["index"]:>6} {r["recorded_status"]!s:>9} '
                    f'{r["replayed_status"]!s:>9} {1e3 * d:16.6f}'
                )
            print(f'\nreplayed bag: {new}')
            return 0
        if args.command == 'bag':
            from activesurv_bringup.salvage import reindex

            print(json.dumps(reindex(args.bag).as_dict(), indent=2))
            return 0
        if args.command == 'report':
            from activesurv_bringup.report import report, summary_table

            docs, path = report(args.path)
            print(summary_table(docs))
            print(f'\nreport: {path}')
            return 0
        if args.command == 'demo':
            from activesurv_bringup.report import summary_table, write_report

            docs = []
            started = time.monotonic()
            for set_name in ('A', 'B'):
                for system in SYSTEMS:
                    out = args.out / f'{set_name}_{system}'
                    if out.exists():
                        import shutil

                        shutil.rmtree(out)
                    print(
                        f'activesurv demo: Set {set_name}, {system} system ({args.mode})',
                        flush=True,
                    )
                    docs.append(run_experiment(args, out, set_name, system, args.seed))
            path = write_report(docs, args.out)
            print(f'\nactivesurv demo: six runs in {time.monotonic() - started:.0f} s\n')
            print(summary_table(docs))
            print(f'\nreport: {path}\nresults: {args.out}/*/results.json')
            (args.out / 'demo.json').write_text(
                json.dumps({'seconds': time.monotonic() - started, 'mode': args.mode}, indent=2)
            )
            return 0
    except (BringupError, OSError, ValueError) as exc:
        print(f'activesurv {args.command}: error: {exc}', file=sys.stderr)
        return 1
    return 2


if __name__ == '__main__':
    sys.exit(main())
