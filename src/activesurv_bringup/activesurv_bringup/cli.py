"""The ``activesurv`` command: demo, experiments, reports and commissioning tools."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from activesurv_bringup.errors import BringupError


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='activesurv', description='Active-vision multi-camera surveillance (ROS 2 Jazzy).'
    )
    sub = parser.add_subparsers(dest='command', required=True)
    demo = sub.add_parser('demo', help='run the main job: the node graph and its summary')
    demo.add_argument('--out', type=Path, default=Path('runs/demo'), help='output directory')
    demo.add_argument('--seed', type=int, default=1, help='random seed')
    stages = sub.add_parser('stages', help='commissioning of stage controllers (probe, move)')
    from activesurv_stages.cli import add_arguments

    add_arguments(stages.add_subparsers(dest='stages_command', required=True))
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    if args.command == 'stages':
        from activesurv_stages.cli import run

        return run(args)
    try:
        if args.command == 'demo':
            from activesurv_bringup.demo import print_summary, run_demo

            print_summary(run_demo(args.out, seed=args.seed))
            print(f'\nresults: {args.out / "results.json"}')
            return 0
    except (BringupError, TimeoutError, OSError) as exc:
        print(f'activesurv {args.command}: error: {exc}', file=sys.stderr)
        return 1
    return 2


if __name__ == '__main__':
    sys.exit(main())
