"""One way to hold a graph: start it, wait until its nodes are up, stop it on every way out.

::

    with GraphSession(launcher, specs, observer.missing, observer.spin) as graph:
        while not done():
            graph.check()          # a dead required node, or a signal: raises
            observer.spin(0.25)
    # every node stopped (the last started first); StopRequested if a signal ended it

The orchestrator's own ROS node (``observer``) answers which named nodes are not up yet and spins;
this module needs no ROS client library. SIGINT, SIGTERM and SIGHUP inside the session ask for a
clean stop (:attr:`GraphSession.stopping`): the caller finishes what it must (open demands
answered, the recorder drained) and leaves the block, and the session then raises
:class:`~activesurv_common.lifetime.StopRequested`. Whatever ends the block, an exception
included, the nodes are stopped; the processes die with this one anyway (parent-death signal).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from types import TracebackType

from activesurv_common.lifetime import StopRequested, StopSignals
from activesurv_launch.errors import NodeDiedError
from activesurv_launch.launcher import NodeSpec
from activesurv_launch.runner import NodeRunner


class GraphSession:
    """Start ``specs`` on ``runner`` and hold them until the block ends.

    Args:
        runner: a Launcher (processes) or a Composition (this process).
        specs: the nodes to start on entry (more may follow with :meth:`start`).
        missing: which of the awaited nodes are not up yet (empty: all up).
        spin: spins the observer for at most the given seconds.
        startup_timeout: seconds for the nodes to come up.
        settle: seconds to spin once they are up (latched topics, subscriptions match).
        trap_signals: SIGINT, SIGTERM and SIGHUP set :attr:`stopping` (a run that drains and
            closes its bag); False: they unwind the block as KeyboardInterrupt (commissioning,
            replay: nothing to finish), and the nodes are stopped all the same.
    """

    def __init__(
        self,
        runner: NodeRunner,
        specs: Sequence[NodeSpec],
        missing: Callable[[], Collection[str]],
        spin: Callable[[float], None],
        startup_timeout: float = 60.0,
        settle: float = 1.0,
        trap_signals: bool = True,
    ) -> None:
        self.runner = runner
        self.specs = list(specs)
        self.missing = missing
        self.spin = spin
        self.startup_timeout = startup_timeout
        self.settle = settle
        self.trap_signals = trap_signals
        self._signals = StopSignals()

    @property
    def stopping(self) -> str:
        """The signal that asked the run to stop ('' while none has)."""
        return self._signals.requested

    def __enter__(self) -> GraphSession:
        if self.trap_signals:
            self._signals.__enter__()
        try:
            self.start(self.specs)
            self.wait_up()
        except BaseException:
            self._close()
            raise
        return self

    def start(self, specs: Sequence[NodeSpec]) -> None:
        """Start more nodes (the clock or the table last)."""
        self.runner.run(specs)

    def wait_up(self) -> None:
        """Wait until :attr:`missing` is empty, then let discovery settle.

        Raises:
            NodeDiedError: if a node dies or they do not come up in time.
            StopRequested: if a signal came meanwhile.
        """
        deadline = time.monotonic() + self.startup_timeout
        while gone := self.missing():
            self.raise_if_stopping()
            self.check()
            if time.monotonic() > deadline:
                raise NodeDiedError(
                    f'nodes did not come up in {self.startup_timeout:.0f} s: {sorted(gone)}'
                )
            self.spin(0.2)
        self.spin(self.settle)
        self.check()
        self.raise_if_stopping()

    def check(self) -> None:
        """Raise NodeDiedError if a required node died."""
        self.runner.check()

    def raise_if_stopping(self) -> None:
        """StopRequested now if a signal came (while the graph starts: nothing to finish)."""
        if self.stopping:
            raise StopRequested(self.stopping)

    def _close(self) -> None:
        try:
            self.runner.stop()
        finally:
            self._signals.__exit__(None, None, None)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        requested = self.stopping
        self._close()
        if requested and exc_type is None:
            raise StopRequested(requested)
