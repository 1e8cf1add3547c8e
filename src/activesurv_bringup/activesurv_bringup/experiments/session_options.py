"""A surveillance session's options (``activesurv surveil``), light to import: the command
line is checked against them before anything heavy is loaded (a refusal within a second)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.rig.rigs import RigChoice
from activesurv_sim.stream import MAX_AT_ONCE, PATH_KINDS, scripted_passes

# Where the Set A cameras can serve (their placement covers the paper's tracking region).
DEMAND_REGION = (0.10, 0.40, 0.0, 0.2)
FIRST_ENTRY = 1.0  # s of simulated time when the first object enters


@dataclass(frozen=True)
class SurveilOptions:
    """What a continuous session does (``activesurv surveil``).

    Attributes:
        duration: simulated seconds to run (None: until SIGINT/SIGTERM).
        arrival_interval: s from one object's entry to the next's (at the earliest).
        demand_interval: s between an object's demands, from its entry.
        demand_at: x (m) of demand lines; if given, demands are their predicted crossings.
        max_bag_duration: split the bag into files of this many s (0: one file).
        max_bag_size: split the bag into files of this many MB (0: no limit).
        keep_bags: keep only the newest N files of the split bag (0: all).
        system: the cameras' motion class.
        seed: seeds the objects' paths and the image noise.
        path_kinds: the path kinds objects are drawn from.
        rig: the rig and calibration (``--rig``, ``--calibration``); None: the set-up is the
            truth.
        objects_at_once: objects on the table at once (lanes; their arrivals overlap, one
            every ``arrival_interval`` / N s).
        script: scripted objects instead of drawn ones (a named set's scene; see
            :class:`~activesurv_sim.stream.ObjectStream`); ``objects_at_once`` must be the
            number of lanes it uses.
        set_name: the named experiment set the session runs (``experiment --set C``), if any.
    """

    duration: float | None = None
    arrival_interval: float = 30.0
    demand_interval: float = 2.0
    demand_at: tuple[float, ...] = ()
    max_bag_duration: float = 0.0
    max_bag_size: float = 0.0
    keep_bags: int = 0
    system: str = 'fast'
    seed: int = 1
    path_kinds: tuple[str, ...] = PATH_KINDS
    rig: RigChoice | None = None  # the simulated hardware and what the system is told
    objects_at_once: int = 1
    script: tuple[dict[str, Any], ...] = ()
    set_name: str | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.objects_at_once <= MAX_AT_ONCE:
            raise ConfigError(
                f'--objects-at-once must be 1 to {MAX_AT_ONCE} (lanes of the table), '
                f'got {self.objects_at_once}'
            )
        if self.duration is not None and not (
            math.isfinite(self.duration) and self.duration > 0.0
        ):
            raise ConfigError(f'--duration must be > 0 s, got {self.duration}')
        for name in ('arrival_interval', 'demand_interval'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ConfigError(f'--{name.replace("_", "-")} must be > 0 s, got {v}')
        if not (math.isfinite(self.max_bag_duration) and self.max_bag_duration >= 0.0):
            raise ConfigError(f'--max-bag-duration must be >= 0 s, got {self.max_bag_duration}')
        if not (math.isfinite(self.max_bag_size) and self.max_bag_size >= 0.0):
            raise ConfigError(f'--max-bag-size must be >= 0 MB, got {self.max_bag_size}')
        if self.keep_bags < 0:
            raise ConfigError(f'--keep-bags must be >= 0, got {self.keep_bags}')
        if self.keep_bags and not (self.max_bag_duration or self.max_bag_size):
            raise ConfigError('--keep-bags needs --max-bag-duration or --max-bag-size')
        x0, x1 = 0.0, 0.5
        for x in self.demand_at:
            if not (math.isfinite(x) and x0 <= x <= x1):
                raise ConfigError(f'--demand-at x={x}: a line must cross the table ({x0}..{x1} m)')
        bad = [k for k in self.path_kinds if k not in PATH_KINDS]
        if bad or not self.path_kinds:
            raise ConfigError(
                f'path kinds must be among {PATH_KINDS}, got {list(self.path_kinds)}'
            )
        if self.script:
            lanes = {p.slot for p in scripted_passes(self.script)}  # refuses a bad script
            if self.objects_at_once != max(lanes) + 1:
                raise ConfigError(
                    f'the script uses {max(lanes) + 1} lanes; objects at once '
                    f'{self.objects_at_once}'
                )

    @classmethod
    def from_args(cls, args: Any, rig: RigChoice | None = None) -> SurveilOptions:
        """The options of ``activesurv surveil`` (checked on the way: ConfigError)."""
        return cls(
            rig=rig,
            duration=args.duration,
            arrival_interval=args.arrival_interval,
            demand_interval=args.demand_interval,
            demand_at=parse_demand_at(args.demand_at),
            max_bag_duration=args.max_bag_duration,
            max_bag_size=args.max_bag_size,
            keep_bags=args.keep_bags,
            system=args.system,
            seed=args.seed,
            objects_at_once=args.objects_at_once,
        )


def parse_demand_at(texts: Sequence[str]) -> tuple[float, ...]:
    """``x=0.25`` (a line x = 0.25 m) for each text.

    Raises:
        ConfigError: for anything else.
    """
    out = []
    for text in texts:
        key, _, value = text.partition('=')
        try:
            if key.strip() != 'x':
                raise ValueError
            out.append(float(value))
        except ValueError:
            raise ConfigError(f'--demand-at {text!r}: expected x=X (metres)') from None
    return tuple(out)
