"""A DDS domain of its own for a simulated run, so that it never reaches a real rig.

A simulated run publishes stage goals (``camN/stage/goal``) that a real ``stage_bridge`` on the
same ROS domain would obey. Unless the user chose a domain (``ROS_DOMAIN_ID`` set), a simulated
run claims a free domain id for its lifetime (a lock file per id, shared by every activesurv
process and test session on the machine) and discovers over localhost only (unless
``ROS_AUTOMATIC_DISCOVERY_RANGE`` is set). Hardware runs and the lab use the caller's domain,
as real drivers do.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from collections.abc import MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from activesurv_launch.errors import LaunchError

# Fast DDS maps domain d to UDP ports 7400 + 250 d (+ offsets); ids above 101 reach Linux's
# ephemeral ports. 0 is the default every ROS 2 tool uses: never claimed.
DOMAIN_IDS = range(11, 102)


@dataclass
class DomainClaim:
    """A domain id held by this process (its lock file stays open until :meth:`release`)."""

    domain_id: int
    chosen_by_user: bool
    handle: IO[str] | None = None

    def release(self) -> None:
        if self.handle is not None:
            self.handle.close()
            self.handle = None


def lock_dir() -> Path:
    d = Path(tempfile.gettempdir()) / 'activesurv-ros-domains'
    d.mkdir(exist_ok=True)
    return d


def claim_domain_id(start: int | None = None) -> tuple[int, IO[str]]:
    """A domain id no other activesurv process or test session on this machine holds.

    Raises:
        LaunchError: when every id of :data:`DOMAIN_IDS` is taken.
    """
    ids = list(DOMAIN_IDS)
    first = (os.getpid() if start is None else start) % len(ids)
    for k in range(len(ids)):
        domain = ids[(first + k) % len(ids)]
        handle = open(lock_dir() / f'{domain}.lock', 'w')  # noqa: SIM115 - held while running
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        return domain, handle
    raise LaunchError(f'no free ROS domain id in {DOMAIN_IDS.start}..{DOMAIN_IDS.stop - 1}')


def isolate(env: MutableMapping[str, str]) -> DomainClaim:
    """Give a simulated run a domain of its own in ``env`` (usually ``os.environ``).

    A ``ROS_DOMAIN_ID`` already in ``env`` is the user's choice and is kept; otherwise a free
    id is claimed and localhost discovery set (a discovery range the user set is kept).
    """
    if env.get('ROS_DOMAIN_ID', '').strip():
        return DomainClaim(int(env['ROS_DOMAIN_ID']), chosen_by_user=True)
    domain, handle = claim_domain_id()
    env['ROS_DOMAIN_ID'] = str(domain)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env.pop('ROS_LOCALHOST_ONLY', None)  # the deprecated switch would contradict the range
    return DomainClaim(domain, chosen_by_user=False, handle=handle)
