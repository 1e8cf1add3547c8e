"""Named experiment sets of our own beside the paper's A and B: scripted scenes of several
objects and the cell's obstacles (``experiments.yaml``, ``scenes``).

A scene is run as a short surveillance session of its scripted objects
(:class:`~activesurv_sim.stream.ObjectStream` with a ``script``) on the run's rig with the
scene's obstacles added to it: the same graph, per-object demands, results and report as
``surveil``, over a fixed span. The rig's calibration is the rig's own: an obstacle put into
the cell for the experiment does not change what commissioning measured.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.files import config_path
from activesurv_bringup.rig.rigs import RigChoice
from activesurv_common.errors import CommonError
from activesurv_common.occlusion import Obstacle, obstacles_from_list
from activesurv_sim.stream import scripted_passes

SCENES = ('C',)
END_MARGIN = 1.5  # s the session runs on after the last object has left


@dataclass(frozen=True)
class Scene:
    """A named set's scene.

    Attributes:
        name: the set's name (``C``).
        description: one line for the report.
        objects: the scripted objects (``{enter, slot, path}`` each).
        obstacles: solids added to the rig for the experiment (world frame).
        demand_interval: s between one object's demands (objects' instants staggered).
        duration: simulated s the session runs (the last object leaves, plus a margin).
        lanes: lanes the objects use (objects at once at most).
    """

    name: str
    description: str
    objects: tuple[dict[str, Any], ...]
    obstacles: tuple[Obstacle, ...]
    demand_interval: float
    duration: float
    lanes: int

    def on(self, choice: RigChoice) -> RigChoice:
        """The run's rig with the scene's obstacles in the cell (same calibration)."""
        rig = replace(choice.rig, obstacles=(*choice.rig.obstacles, *self.obstacles))
        return replace(choice, rig=rig)


def load_scene(name: str, config_file: Path | None = None) -> Scene:
    """The named set ``name`` of ``experiments.yaml`` (default: the packaged one).

    Raises:
        ConfigError: for an unknown name or a bad scene.
    """
    if name not in SCENES:
        raise ConfigError(f'unknown scene {name!r}; choose from {SCENES}')
    path = config_file or config_path()
    try:
        doc = yaml.safe_load(Path(path).read_text())['scenes'][name]
        objects = tuple(dict(o) for o in doc['objects'])
        passes = scripted_passes(objects)
        obstacles = obstacles_from_list(doc.get('obstacles') or [])
        interval = float(doc['demand_interval'])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError, CommonError) as exc:
        # (a bad path is the stages' ConfigError: a ValueError)
        raise ConfigError(f'{path}: scene {name}: {exc}') from None
    if not interval > 0.0:
        raise ConfigError(f'{path}: scene {name}: demand_interval must be > 0 s')
    return Scene(
        name,
        str(doc.get('description', '')),
        objects,
        obstacles,
        interval,
        max(p.left for p in passes) + END_MARGIN,
        max(p.slot for p in passes) + 1,
    )
