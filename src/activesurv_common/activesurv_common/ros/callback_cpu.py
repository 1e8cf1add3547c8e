"""Where a process's CPU goes, callback by callback: a diagnostic (``ACTIVESURV_CALLBACK_CPU``).

With the environment variable ``ACTIVESURV_CALLBACK_CPU`` set to a directory (or to ``1``:
``./callbacks``), a node process (:func:`activesurv_common.ros.node.run_node`, a container)
times every subscription and timer callback of its nodes on the thread's CPU clock, and every
``publish`` apart, and writes ``<dir>/<process>.json`` when it stops::

    {"process": "/core", "cpu_seconds": 2.64,
     "callbacks": {"sub predictor overhead/fix": [108, 0.856], ...},
     "publish": {"/demand_horizon": [108, 0.015], ...}}

(``[calls, CPU seconds]``; ``cpu_seconds`` is the process's whole CPU, its start included).
Beside it, ``<process>.trace`` holds each call (the last :data:`TRACE_LIMIT`) as
``[wall start, wall end, CPU seconds, name]`` (``time.time()``, one clock for every process of
the machine; publishes named ``pub <topic>``): what ran where around a demand instant
(:mod:`activesurv_evaluation.timeline` draws it).
A callback's CPU includes what it hands on in process: the members of a container that hear
a topic in process (:mod:`activesurv_common.ros.local_topics`) run inside the publisher's
callback, and its publishing. Unset (the default) nothing is wrapped. ``activesurv experiment``
with the variable set (any value) collects the files into ``cpu.json`` (``callbacks``).
The cost of the timing itself is four clock reads and an append a callback (1.4 µs here, `timeit`).
"""

from __future__ import annotations

import collections
import functools
import json
import os
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ENV = 'ACTIVESURV_CALLBACK_CPU'

_TALLY: dict[str, dict[str, list[float]]] = {'callbacks': {}, 'publish': {}}
_INSTALLED = [False]
TRACE_LIMIT = 200_000
"""Calls kept in the trace (the last ones; about 100 bytes each)."""
_TRACE: collections.deque[tuple[float, float, float, str]] = collections.deque(maxlen=TRACE_LIMIT)


def enabled() -> bool:
    """Whether this process times its callbacks (the variable names a directory)."""
    return bool(os.environ.get(ENV, ''))


def output_dir() -> Path:
    """Where the tallies go: the directory the variable names; for a plain yes (``1``,
    ``true``, ``yes``, ``on``), ``callbacks`` in the working directory."""
    value = os.environ.get(ENV, '')
    return Path('callbacks') if value.lower() in YES else Path(value)


YES = ('1', 'true', 'yes', 'on')


def _timed(kind: str, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    entry = _TALLY[kind].setdefault(name, [0, 0.0])
    clock, wall, trace = time.thread_time, time.time, _TRACE.append

    @functools.wraps(fn)  # rclpy reads the callback's signature (message info or not)
    def timed(*args: Any, **kwargs: Any) -> Any:
        w0, t0 = wall(), clock()
        try:
            return fn(*args, **kwargs)
        finally:
            cpu = clock() - t0
            entry[0] += 1
            entry[1] += cpu
            trace((w0, wall(), cpu, name))

    return timed


def _callback_name(callback: Any) -> str:
    name = getattr(callback, '__qualname__', None) or type(callback).__name__
    return str(name).replace('.<locals>', '')


def install() -> bool:
    """Wrap the callbacks of every node made in this process from now on (before the nodes are
    built), if :func:`enabled`. Returns whether it did."""
    if not enabled() or _INSTALLED[0]:
        return _INSTALLED[0]
    from rclpy.node import Node
    from rclpy.publisher import Publisher

    subscribe, timer, publish = Node.create_subscription, Node.create_timer, Publisher.publish

    def create_subscription(
        self: Node, msg_type: Any, topic: str, callback: Any, *a: Any, **k: Any
    ) -> Any:
        name = f'sub {self.get_name()} {topic}'
        return subscribe(self, msg_type, topic, _timed('callbacks', name, callback), *a, **k)

    def create_timer(self: Node, period: float, callback: Any, *a: Any, **k: Any) -> Any:
        name = f'timer {self.get_name()} {_callback_name(callback)}'
        return timer(self, period, _timed('callbacks', name, callback), *a, **k)

    def timed_publish(self: Publisher, msg: Any) -> None:
        entry = _TALLY['publish'].setdefault(self.topic_name, [0, 0.0])
        w0, t0 = time.time(), time.thread_time()
        try:
            publish(self, msg)
        finally:
            cpu = time.thread_time() - t0
            entry[0] += 1
            entry[1] += cpu
            _TRACE.append((w0, time.time(), cpu, f'pub {self.topic_name}'))

    Node.create_subscription = create_subscription  # type: ignore[method-assign]
    Node.create_timer = create_timer  # type: ignore[method-assign,assignment]
    Publisher.publish = timed_publish  # type: ignore[method-assign]
    _INSTALLED[0] = True
    return True


def tally() -> dict[str, dict[str, list[float]]]:
    """What was timed so far: ``{'callbacks': {name: [calls, s]}, 'publish': {topic: ...}}``."""
    return {k: {n: [int(v[0]), round(v[1], 6)] for n, v in d.items()} for k, d in _TALLY.items()}


def write(process: str) -> Path | None:
    """Write this process's tally to ``$ACTIVESURV_CALLBACK_CPU/<process>.json`` and its calls
    to ``<process>.trace`` beside it (if it timed anything); returns the tally's file. A
    directory that cannot be written is skipped (a diagnostic never stops a node)."""
    if not _INSTALLED[0]:
        return None
    own = os.times()
    doc = {'process': process, 'cpu_seconds': round(own.user + own.system, 3), **tally()}
    stem = re.sub(r'[^A-Za-z0-9_.-]+', '_', process.strip('/')) or 'process'
    try:
        directory = output_dir()
        directory.mkdir(parents=True, exist_ok=True)
        path = directory / f'{stem}.json'
        path.write_text(json.dumps(doc, indent=1) + '\n')
        calls = [[round(a, 6), round(b, 6), round(c, 6), n] for a, b, c, n in _TRACE]
        (directory / f'{stem}.trace').write_text(json.dumps({'process': process, 'calls': calls}))
    except OSError:
        return None
    return path


def collect(directory: Path) -> dict[str, Any]:
    """The tallies of a run's processes (the files :func:`write` left in ``directory``), by
    process; unreadable files are skipped."""
    out: dict[str, Any] = {}
    for path in sorted(directory.glob('*.json')):
        try:
            doc = json.loads(path.read_text())
            out[str(doc['process'])] = {k: doc[k] for k in ('cpu_seconds', 'callbacks', 'publish')}
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return out


def top(collected: dict[str, Any], n: int = 12) -> list[dict[str, Any]]:
    """The ``n`` callbacks that took the most CPU in ``collected`` (:func:`collect`), most
    first: process, callback, calls, CPU seconds, ms a call."""
    rows = [
        {
            'process': process,
            'callback': name,
            'calls': int(calls),
            'cpu_s': round(float(s), 4),
            'ms_per_call': round(1e3 * float(s) / max(int(calls), 1), 3),
        }
        for process, doc in collected.items()
        for name, (calls, s) in doc.get('callbacks', {}).items()
    ]
    rows.sort(key=lambda r: -r['cpu_s'])
    return rows[:n]
