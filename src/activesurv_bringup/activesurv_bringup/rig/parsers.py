"""The arguments of ``activesurv hardware ...`` and ``activesurv rig ...`` (what ``--help``
shows; the commands themselves are :func:`activesurv_bringup.rig.hardware.run` and
:func:`activesurv_bringup.rig.rigs.run`). Light on purpose: ``activesurv --help`` builds every
subcommand's parser and must not load the schemas, numpy or the ROS client library."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_hardware_arguments(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``activesurv hardware {template,check,schema}``."""
    t = sub.add_parser('template', help="write a commented hardware file (the paper's rig)")
    t.add_argument('--out', type=Path, required=True, help='file to write (must not exist)')
    t.add_argument('--name', default='paper-lab', help='the rig name in the file')
    t.add_argument('--namespace', default='', help="ROS namespace of the rig's topics")
    c = sub.add_parser(
        'check',
        help='read a hardware file and say what it describes, or every mistake in it (exit 2)',
    )
    c.add_argument('file', type=Path, help='the hardware file')
    c.add_argument(
        '--offline',
        action='store_true',
        help="check the file only, not that its controllers' ports exist and are usable",
    )
    md = sub.add_parser(
        'measure-delay',
        help="measure each camera's exposure delay and stamp jitter by sweeping the board on "
        'the table in front of it; writes CALDIR/delays.yaml, which hardware runs use',
    )
    md.add_argument('--hardware', type=Path, required=True, help="the rig's hardware file")
    md.add_argument(
        '--calibration',
        type=Path,
        required=True,
        help='the commissioned calibration directory (plans the sweeps; delays.yaml goes there)',
    )
    md.add_argument(
        '--cameras', default=None, help='comma-separated cameras, overhead included (default: all)'
    )
    md.add_argument(
        '--home', action='store_true', help='home unreferenced axes when the bridges connect'
    )
    md.add_argument('--yes', action='store_true', help='move without asking')
    sc = sub.add_parser(
        'schema', help="write the hardware file's JSON Schema (for an editor's YAML server)"
    )
    sc.add_argument('--out', type=Path, required=True, help='file to write (must not exist)')


def add_rig_arguments(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``activesurv rig {nominal,perturb}``."""
    nom = sub.add_parser('nominal', help="write the paper's nominal rig")
    nom.add_argument('--out', type=Path, required=True, help='rig YAML to write (must not exist)')
    per = sub.add_parser('perturb', help='draw a realistic rig near a given one')
    per.add_argument(
        '--in', dest='source', type=Path, required=True, help='rig YAML to start from'
    )
    per.add_argument('--seed', type=int, required=True, help='seed of the perturbation')
    per.add_argument('--out', type=Path, required=True, help='rig YAML to write (must not exist)')
