"""In-process mode: every node of a run composed in one process, on one executor.

The same :class:`~activesurv_launch.launcher.NodeSpec` list as graph mode, but each
node is constructed here (its name and namespace remapped, its parameters as overrides) and
spun by one executor in a background thread, like a component container. Useful to debug a
whole run in one
process; on two cores it keeps up with rtf 0.5, not 1 (one interpreter does all the work).
"""

from __future__ import annotations

import importlib
import threading
import time
from collections.abc import Sequence
from typing import Any

from activesurv_launch.launcher import NodeSpec

NODE_CLASSES = {
    'activesurv_recording.recorder_node': 'RecorderNode',
    'activesurv_liveview.frames_node': 'FramesNode',
    'activesurv_liveview.live_view_node': 'LiveViewNode',
    'activesurv_sim.sim_camera_node': 'SimCameraNode',
    'activesurv_imaging.imager_node': 'ImagerNode',
    'activesurv_prediction.predictor_node': 'PredictorNode',
    'activesurv_imaging.overhead_locator_node': 'OverheadLocatorNode',
    'activesurv_dispatch.dispatcher_node': 'DispatcherNode',
    'activesurv_fusion.fusion_node': 'FusionNode',
    'activesurv_sim.sim_stage_node': 'SimStageNode',
    'activesurv_sim.xy_table_node': 'XYTableNode',
}


def build_node(spec: NodeSpec) -> Any:
    """Construct the node of ``spec`` in this process."""
    from rclpy.parameter import Parameter  # rclpy only in the composing process

    cls = getattr(importlib.import_module(spec.module), NODE_CLASSES[spec.module])
    args = ['--ros-args', '-r', f'__node:={spec.name}']
    if spec.namespace:
        args += ['-r', f'__ns:=/{spec.namespace.strip("/")}']
    for src, dst in spec.remappings.items():
        args += ['-r', f'{src}:={dst}']
    overrides = [Parameter(k, value=v) for k, v in spec.parameters.items()]
    return cls(cli_args=args, parameter_overrides=overrides)


def share_clock(nodes: Sequence[Any]) -> int:
    """Let the first simulated-time node's /clock subscription drive every member's clock.

    rclpy gives each node a time source with its own /clock subscription; in one process
    that is one Python callback per node per tick. The others are detached (their
    subscription destroyed) and their clocks attached to the first time source. Their
    ``use_sim_time`` is then fixed for the life of the container.

    Returns:
        How many /clock subscriptions were saved.
    """
    sim = [n for n in nodes if n._time_source.ros_time_is_active]
    if len(sim) < 2:
        return 0
    first = sim[0]._time_source
    for node in sim[1:]:
        node._time_source.detach_node()
        first.attach_clock(node.get_clock())
    return len(sim) - 1


class Composition:
    """Nodes spinning on one executor in a background thread."""

    def __init__(self, threads: int = 4) -> None:
        # Not the EventsExecutor: nodes are added while it spins in another thread.
        from rclpy.executors import MultiThreadedExecutor

        self.executor = MultiThreadedExecutor(num_threads=threads)
        self.nodes: list[Any] = []
        self._thread: threading.Thread | None = None

    def add(self, specs: Sequence[NodeSpec]) -> None:
        new = [build_node(spec) for spec in specs]
        share_clock([*self.nodes[:1], *new])  # the first node's /clock drives the others
        for node in new:
            self.nodes.append(node)
            self.executor.add_node(node)
        if self._thread is None:
            self._thread = threading.Thread(target=self.executor.spin, daemon=True)
            self._thread.start()

    def run(self, specs: Sequence[NodeSpec]) -> None:
        """Start ``specs``: :class:`~activesurv_launch.runner.NodeRunner`."""
        self.add(specs)

    def check(self) -> None:
        """Composed nodes cannot die alone: a crash takes the process (nothing to check)."""

    def cpu_seconds(self) -> dict[str, float]:
        return {}  # one process: the orchestrator's own, counted by it

    def rss_bytes(self) -> dict[str, int]:
        return {}

    def stop(self) -> None:

        for node in self.nodes:
            flush = getattr(node, 'flush', None)
            if callable(flush):
                flush()  # fusion answers its open demands while the recorder still listens
        time.sleep(0.5)
        self.executor.shutdown(timeout_sec=2.0)
        for node in self.nodes:
            close = getattr(node, 'close', None)
            if callable(close):
                close()  # the recorder closes its bag
        for node in reversed(self.nodes):
            node.destroy_node()
