"""rclpy's logger without the source lookup on every call.

``node.get_logger().info(...)`` identifies its caller (for the ``once``/``throttle`` filters and
the log line's location) with ``inspect.getframeinfo`` and ``os.path.realpath``: every call
reads the caller's source file's status and resolves its path, a handful of system calls. On
this project's two-core test machine (nested virtualisation, where a system call is dear) that
made fusion's one line per demand cost more CPU than fusing the demand (py-spy, a Set A fast
run: 5 % of fusion's samples in ``getframeinfo``/``realpath``/``fstatat``).

:func:`install` replaces how rclpy builds that caller id with the frame's own fields (function,
file name as compiled, line): the same id for the same call site, nothing read from disk. The
log lines, filters and ``/rosout`` are unchanged. Our processes install it at start
(:func:`activesurv_common.ros.node.run_node`, the containers); ``ACTIVESURV_FAST_LOGGING=0``
leaves rclpy as it is.
"""

from __future__ import annotations

import os
import sys
from types import FrameType
from typing import Any

_INSTALLED = False


def _internal_files() -> frozenset[str]:
    import rclpy.impl.rcutils_logger as impl
    import rclpy.logging

    files = {impl.__file__, rclpy.logging.__file__}
    return frozenset(files | {os.path.realpath(f) for f in files})


def install() -> bool:
    """Make rclpy's caller lookup cheap (idempotent); False if rclpy's internals differ from
    what this expects (then nothing is changed) or ``ACTIVESURV_FAST_LOGGING=0``."""
    global _INSTALLED
    if _INSTALLED:
        return True
    if os.environ.get('ACTIVESURV_FAST_LOGGING', '1') == '0':
        return False
    try:
        import rclpy.impl.rcutils_logger as impl

        caller_id = impl.CallerId
        fields = caller_id._fields
    except (ImportError, AttributeError):
        return False
    if tuple(fields) != ('function_name', 'file_path', 'line_number', 'last_index'):
        return False
    internal = _internal_files()

    def fast_new(cls: type, frame: FrameType | None = None) -> Any:
        if not frame:
            f: FrameType | None = sys._getframe(1)
            while f is not None and f.f_code.co_filename in internal:
                f = f.f_back
            if f is None:  # only rclpy on the stack: as rclpy would, the outermost frame
                f = sys._getframe(1)
            frame = f
        code = frame.f_code
        return tuple.__new__(cls, (code.co_name, code.co_filename, frame.f_lineno, frame.f_lasti))

    caller_id.__new__ = fast_new  # type: ignore[method-assign]
    _INSTALLED = True
    return True
