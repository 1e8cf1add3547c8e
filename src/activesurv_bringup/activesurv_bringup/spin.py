"""Run a node until SIGINT/SIGTERM, then let it finish its work (close a bag, write a summary)."""

from __future__ import annotations

import signal
import sys
from collections.abc import Callable
from types import FrameType
from typing import TypeVar

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

N = TypeVar('N', bound=Node)


def run_until_signal(
    name: str,
    make_node: Callable[[], N],
    on_stop: Callable[[N], None],
    args: list[str] | None = None,
    errors: tuple[type[Exception], ...] = (ValueError,),
) -> int:
    """Spin ``make_node()`` until a stop signal; ``on_stop(node)`` runs before the context ends.

    rclpy's own signal handler would shut the context down first; here the node still has its
    publishers and files when it stops. A construction error in ``errors`` prints one line to
    stderr and returns 1.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = make_node()
    except errors as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stopping = False

    def _stop(signum: int, frame: FrameType | None) -> None:
        nonlocal stopping
        stopping = True

    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    try:
        while rclpy.ok() and not stopping:
            executor.spin_once(timeout_sec=0.05)
    finally:
        on_stop(node)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
