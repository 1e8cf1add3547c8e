"""How a graph run is run (``RunOptions``) and where its files go (output directories).

Output directories are never deleted or overwritten: a directory that already holds files is
refused, and commands without an explicit ``--out`` make a new timestamped one, as ``ros2 bag
record`` does.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from activesurv_bringup.errors import ConfigError
from activesurv_bringup.experiments.faults import Fault, Kill
from activesurv_launch.launcher import NodeSpec

HOSTS = ('single', 'netns')
# One worker thread per numerical library in each node process: a graph is many processes on
# few cores, and OpenBLAS's and OpenCV's worker pools (which spin while they wait) only fought
# each other there (frames took 2-4x longer). A value the user has set is kept.
THREAD_LIMITS = {
    'OPENBLAS_NUM_THREADS': '1',
    'OMP_NUM_THREADS': '1',
    'MKL_NUM_THREADS': '1',
    'OPENCV_FOR_THREADS_NUM': '1',
}
PROCESSES = ('containers', 'nodes')


RECORD_FRAMES = ('used', 'all', 'none')


@dataclass(frozen=True)
class RunOptions:
    """Everything about a graph run that is not the experiment itself.

    Attributes:
        rtf: simulated seconds per wall second.
        image_rate: Hz of the thinned image topics in the bag (0: all).
        faults: camera faults to inject.
        kills: nodes to SIGKILL (and restart) at simulated instants.
        compose: every node in this process on one executor.
        processes: ``containers`` (nodes grouped into a few processes per host, the default)
            or ``nodes`` (one process per node, as separate ``ros2 run`` calls would).
        hosts: ``single``, or ``netns`` (each camera on a host of its own).
        dds_profile: a Fast DDS XML profile for every node (a path), or None.
        startup_timeout: wall seconds for the graph to come up.
        extra: further nodes started with the graph (load generators).
        thin: further topics the recorder thins to ``image_rate``.
        preview_rate: Hz of the dynamic cameras' preview streams for viewers (0: none).
        time_origin: a hardware run: wall clock (s since the epoch) of run time 0; None: the
            simulator's /clock.
        namespace: a hardware run: the rig's ROS namespace.
        record_frames: a hardware run's dynamic-camera frames in the bag: ``used`` (each frame
            an imager measured for a demand, PNG), ``all`` (every frame) or ``none``.
    """

    rtf: float = 1.0
    image_rate: float = 2.0
    faults: tuple[Fault, ...] = ()
    kills: tuple[Kill, ...] = ()
    compose: bool = False
    processes: str = 'containers'
    hosts: str = 'single'
    dds_profile: Path | None = None
    startup_timeout: float = 60.0
    extra: tuple[NodeSpec, ...] = ()
    thin: tuple[str, ...] = ()
    preview_rate: float = 0.0
    time_origin: float | None = None
    namespace: str = ''
    record_frames: str = 'used'

    def __post_init__(self) -> None:
        if self.record_frames not in RECORD_FRAMES:
            raise ConfigError(
                f'--record-frames must be one of {", ".join(RECORD_FRAMES)}, '
                f'got {self.record_frames!r}'
            )
        if not (math.isfinite(self.rtf) and self.rtf > 0.0):
            raise ConfigError(f'--rtf must be a finite number > 0, got {self.rtf}')
        if not (math.isfinite(self.image_rate) and self.image_rate >= 0.0):
            raise ConfigError(f'--image-rate must be >= 0, got {self.image_rate}')
        if self.processes not in PROCESSES:
            raise ConfigError(f'--processes must be one of {PROCESSES}, got {self.processes!r}')
        if self.hosts not in HOSTS:
            raise ConfigError(f'--hosts must be one of {HOSTS}, got {self.hosts!r}')
        if self.kills and self.compose:
            raise ConfigError('killing nodes needs one process per node (leave out --compose)')
        if self.dds_profile is not None and self.hosts == 'netns':
            raise ConfigError('--dds-profile and --hosts netns do not mix (hosts use UDPv4)')

    def environment(self) -> dict[str, str]:
        """Environment variables every process of the run needs (this one included)."""
        env = {k: v for k, v in THREAD_LIMITS.items() if k not in os.environ}
        if self.dds_profile is not None:
            env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(self.dds_profile)
        if self.hosts == 'netns':
            # Discovery over the bridge (multicast on the subnet); no shared memory between hosts.
            env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SUBNET'
            env['FASTDDS_BUILTIN_TRANSPORTS'] = 'UDPv4'
        return env


@contextlib.contextmanager
def scoped_environ(updates: Mapping[str, str]) -> Iterator[None]:
    """Set environment variables for the duration of a run, then restore them.

    The orchestrator's own DDS participant (progress monitor) must see the same transport
    settings as its node processes, so they go into this process's environment too.
    """
    old = {k: os.environ.get(k) for k in updates}
    os.environ.update(updates)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


__all__ = [
    'HOSTS',
    'PROCESSES',
    'RunOptions',
    'scoped_environ',
]
