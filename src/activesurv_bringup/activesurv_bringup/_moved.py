"""Earlier module paths of bringup, kept working after its split into rooms.

Until the split every bringup module sat in one flat package (``activesurv_bringup.graph``,
``activesurv_bringup.rigs`` ...). Earlier issues and users' scripts name those paths, so an
import of one gets the module from its new room: the very same module object, private names and
monkeypatching included. New code imports the new paths.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType

# Where each module of the flat bringup package went.
MOVED_TO = {
    'activesurv_launch': ('launcher', 'compose', 'container', 'netns'),
    'activesurv_recording': ('bagio', 'salvage', 'recorder_node', 'load_node'),
    'activesurv_liveview': ('live', 'live_view_node', 'frames_node', 'scene'),
    'activesurv_studies': ('sensor_model_experiment', 'prediction_suite'),
    'activesurv_bringup.rig': ('rigs', 'board_views', 'commission', 'lab'),
    'activesurv_bringup.experiments': (
        'experiment',
        'faults',
        'options',
        'graph',
        'lockstep',
        'evaluation',
        'report',
        'surveil',
        'replay',
    ),
}
MOVED = {
    f'activesurv_bringup.{name}': f'{room}.{name}'
    for room, names in MOVED_TO.items()
    for name in names
}


class _Alias(importlib.abc.Loader):
    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        return importlib.import_module(self.target)

    def exec_module(self, module: ModuleType) -> None:
        """The target module ran when it was imported."""


class MovedModules(importlib.abc.MetaPathFinder):
    """Finds an old bringup path and hands out the module of its new path."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        new = MOVED.get(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Alias(new))


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, MovedModules) for f in sys.meta_path):
        sys.meta_path.append(MovedModules())
