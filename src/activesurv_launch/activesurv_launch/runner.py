"""One interface for the ways a run's nodes are started: processes or one composed process.

:class:`~activesurv_launch.launcher.Launcher` (a process per node or per container) and
:class:`~activesurv_launch.ros.compose.Composition` (every node on one executor in this process)
both are a :class:`NodeRunner`; an orchestrator starts nodes in groups, checks on them, stops
them in reverse order and reads what they cost without knowing which it has.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

from activesurv_launch.launcher import NodeSpec


class NodeRunner(Protocol):
    def run(self, specs: Sequence[NodeSpec]) -> None:
        """Start these nodes (others may follow later)."""

    def check(self) -> None:
        """Raise NodeDiedError if a required node died."""

    def stop(self) -> Any:
        """Stop every node, the last started first."""

    def cpu_seconds(self) -> dict[str, float]:
        """CPU seconds so far of each process it started (none when composed here)."""

    def rss_bytes(self) -> dict[str, int]:
        """Resident memory of each process it started (none when composed here)."""
