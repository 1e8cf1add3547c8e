"""``diagnostic_msgs`` helpers: every node reports the same way on ``/diagnostics``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

__all__ = ['ERROR', 'OK', 'WARN', 'DiagnosticArray', 'array', 'status', 'values_of']

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR


def status(
    name: str,
    hardware_id: str,
    message: str,
    values: Mapping[str, Any],
    level: bytes = OK,
) -> DiagnosticStatus:
    """One status; ``values`` become key/value pairs (sorted by key, values as text)."""
    s = DiagnosticStatus(name=name, hardware_id=hardware_id, message=message, level=level)
    s.values = [KeyValue(key=str(k), value=str(v)) for k, v in sorted(values.items())]
    return s


def array(stamp: Time, *statuses: DiagnosticStatus) -> DiagnosticArray:
    arr = DiagnosticArray(status=list(statuses))
    arr.header.stamp = stamp
    return arr


def values_of(arr: DiagnosticArray, name: str) -> dict[str, str] | None:
    """The key/value pairs of the status called ``name`` in ``arr``, or None."""
    for s in arr.status:
        if s.name == name:
            return {kv.key: kv.value for kv in s.values}
    return None
