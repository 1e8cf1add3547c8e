"""Write (or check) ``config/<node>.yaml`` of every node from its declared ``PARAMS``.

    .venv/bin/python scripts/node_configs.py          # write the files
    .venv/bin/python scripts/node_configs.py --check  # exit 1 if one is missing or stale

The YAML files are what ``--params-file`` takes; each key carries its description and bounds
as a comment. ``test/test_node_configs.py`` runs the check, so a parameter added to a node
without its config entry fails the suite.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]

# node name -> (package, module of the node)
NODES: dict[str, tuple[str, str]] = {
    'imager': ('activesurv_imaging', 'imager_node'),
    'overhead_locator': ('activesurv_imaging', 'overhead_locator_node'),
    'predictor': ('activesurv_prediction', 'predictor_node'),
    'dispatcher': ('activesurv_dispatch', 'dispatcher_node'),
    'fusion': ('activesurv_fusion', 'fusion_node'),
    'sim_camera': ('activesurv_sim', 'sim_camera_node'),
    'lab_camera': ('activesurv_sim', 'lab_camera_node'),
    'sim_stage': ('activesurv_sim', 'sim_stage_node'),
    'xy_table': ('activesurv_sim', 'xy_table_node'),
    'stage_bridge': ('activesurv_stages', 'stage_bridge_node'),
    'recorder': ('activesurv_recording', 'recorder_node'),
    'image_load': ('activesurv_recording', 'load_node'),
    'frames': ('activesurv_liveview', 'frames_node'),
    'live_view': ('activesurv_liveview', 'live_view_node'),
    'table_runner': ('activesurv_hardware', 'table_runner_node'),
    'camera': ('activesurv_hardware', 'camera_node'),
}


def _value(v: Any) -> str:
    text = yaml.safe_dump(v, default_flow_style=True, width=1000).strip()
    return text.removesuffix('\n...').strip()


def render(node: str, package: str, module: str) -> str:
    params = importlib.import_module(f'{package}.{module}').PARAMS
    lines = [
        f'# Parameters of the {node} node, with their defaults (generated from {module}.PARAMS',
        '# by scripts/node_configs.py). Use it as a template (the console script is in the',
        "# venv's bin/; with a full ROS 2 install also `ros2 run PACKAGE NODE`):",
        f'#   {node} --ros-args --params-file {node}.yaml   # package {package}',
        f'{node}:',
        '  ros__parameters:',
    ]
    for p in params:
        note = p.descriptor().description
        bounds = [
            f'{op} {v:g}'
            for op, v in (('>=', p.minimum), ('>', p.above), ('<=', p.maximum))
            if v is not None
        ]
        if bounds:
            note += f' [{", ".join(bounds)}]'
        if isinstance(p.default, int | float | str | bool | list):
            lines.append(f'    {p.name}: {_value(p.default)}  # {note}')
        else:
            lines.append(f'    # {p.name}: (unset)  # {note}')
    return '\n'.join(lines) + '\n'


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--check', action='store_true', help='only compare, write nothing')
    args = parser.parse_args(argv)
    stale = []
    for node, (package, module) in NODES.items():
        path = ROOT / 'src' / package / 'config' / f'{node}.yaml'
        text = render(node, package, module)
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(str(path.relative_to(ROOT)))
        else:
            path.parent.mkdir(exist_ok=True)
            path.write_text(text)
            print(f'wrote {path.relative_to(ROOT)}')
    if stale:
        print('stale or missing (run scripts/node_configs.py):\n  ' + '\n  '.join(stale))
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
