"""What ran where around a demand instant: the processes' call traces
(``ACTIVESURV_CALLBACK_CPU``, :mod:`activesurv_common.ros.callback_cpu`) laid on one wall clock.

Each process of a graph run writes ``logs/callbacks/<process>.trace``: every callback and
publish with its wall start and end and its CPU time. A call whose wall time is much longer
than its CPU time waited for a core (or for the GIL); the cores' occupancy over a demand's
window (callbacks' CPU against cores x window) says whether the wait is the machine's. The
demands are placed on the wall clock by fusion's estimates: the k-th estimate fusion
published is the k-th demand with an estimate, published ``timing.estimate`` after its
instant (simulated seconds; wall seconds at rtf 1, divided by the run's rtf otherwise).
"""

from __future__ import annotations

import json
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

Call = tuple[float, float, float, str]
"""Wall start, wall end (s, ``time.time()``), CPU seconds, name."""

ESTIMATE = 'pub /target_estimate'
OBSERVATION = 'pub /marker_observations'
FUSION = 'fusion'


@dataclass(frozen=True)
class Window:
    """One demand on the wall clock: its instant and when fusion published its estimate."""

    index: int
    instant: float
    estimate: float
    latency: float


def load_traces(directory: Path) -> dict[str, list[Call]]:
    """The calls of every process whose trace is in ``directory``, by process name (the file's
    stem), sorted by start; unreadable files are skipped."""
    out: dict[str, list[Call]] = {}
    for path in sorted(directory.glob('*.trace')):
        try:
            doc = json.loads(path.read_text())
            calls = [(float(a), float(b), float(c), str(n)) for a, b, c, n in doc['calls']]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        out[path.stem] = sorted(calls)
    return out


def demand_windows(
    demands: Sequence[dict[str, Any]], traces: dict[str, list[Call]], rtf: float = 1.0
) -> list[Window]:
    """The demands with an estimate, on the wall clock (see the module's note); empty when
    fusion's trace is missing or does not hold one estimate per such demand."""
    estimates = [c[0] for c in traces.get(FUSION, []) if c[3] == ESTIMATE]
    timed = sorted(
        (d for d in demands if (d.get('timing') or {}).get('estimate') is not None),
        key=lambda d: int(d['index']),
    )
    if not timed or len(estimates) != len(timed):
        return []
    out = []
    for d, published in zip(timed, estimates, strict=True):
        after = float(d['timing']['estimate']) / rtf
        out.append(Window(int(d['index']), published - after, published, after))
    return out


def occupancy(traces: dict[str, list[Call]], start: float, end: float) -> float:
    """CPU seconds the callbacks of every process spent in ``[start, end]`` (a call's CPU
    counted in proportion to the part of its wall time inside the window; publishes are
    inside their callbacks and not counted again)."""
    total = 0.0
    for calls in traces.values():
        for a, b, cpu, name in calls:
            if name.startswith('pub ') or b <= start or a >= end:
                continue
            wall = b - a
            inside = min(b, end) - max(a, start)
            total += cpu * (inside / wall if wall > 0 else 1.0)
    return total


def summarise(
    windows: Sequence[Window], traces: dict[str, list[Call]], cores: int
) -> list[dict[str, float]]:
    """Per demand: latency (ms), the callbacks' CPU from the instant to the estimate (ms) and
    the cores' occupancy over that window (0-1)."""
    rows = []
    for w in windows:
        cpu = occupancy(traces, w.instant, w.estimate)
        rows.append(
            {
                'index': w.index,
                'latency_ms': round(1e3 * w.latency, 2),
                'cpu_in_window_ms': round(1e3 * cpu, 2),
                'occupancy': round(cpu / (cores * w.latency), 3) if w.latency > 0 else 0.0,
            }
        )
    return rows


def plot_timeline(
    window: Window, traces: dict[str, list[Call]], path: Path, title: str, cores: int
) -> Path:
    """One demand's window, a lane per process: each call a bar over its wall time, its CPU
    time the dark part; the observations' and the estimate's publication marked."""
    import matplotlib  # heavy: only when a figure is drawn

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    lo, hi = window.instant - 0.002, window.estimate + 0.004
    lanes = sorted(traces, key=lambda p: (p.startswith('cam') is False, p != FUSION, p))
    fig, ax = plt.subplots(figsize=(9.0, 0.45 * len(lanes) + 1.4))
    for y, process in enumerate(lanes):
        shown = [c for c in traces[process] if c[1] >= lo and c[0] <= hi]
        for a, b, cpu, name in shown:
            pub = name.startswith('pub ')
            height = 0.25 if pub else 0.6
            x0, width = 1e3 * (a - window.instant), 1e3 * (b - a)
            ax.barh(y, width, left=x0, height=height, color='tab:blue', alpha=0.25)
            ax.barh(y, min(1e3 * cpu, width), left=x0, height=height, color='tab:blue')
            if name == OBSERVATION:
                ax.plot(x0, y + 0.4, 'v', color='tab:green', ms=6)
            elif name == ESTIMATE:
                ax.plot(x0, y + 0.4, '*', color='tab:red', ms=10)
        longest = max((c for c in shown if not c[3].startswith('pub ')), default=None,
                      key=lambda c: c[1] - c[0])  # fmt: skip
        if longest is not None:
            name = longest[3].split(' ', 1)[-1].replace('_schedule.', '')
            x0 = max(1e3 * (longest[0] - window.instant), 1e3 * (lo - window.instant))
            ax.text(x0, y - 0.42, name[:60], fontsize=6, va='bottom')
    ax.axvline(0.0, color='k', lw=1)
    ax.set_yticks(range(len(lanes)))
    ax.set_yticklabels(lanes, fontsize=8)
    ax.set_xlim(1e3 * (lo - window.instant), 1e3 * (hi - window.instant))
    ax.set_xlabel('ms after the demand instant (wall clock)')
    cpu = occupancy(traces, window.instant, window.estimate)
    ax.set_title(
        f'{title}: demand {window.index}, estimate {1e3 * window.latency:.1f} ms after the '
        f'instant; callbacks used {1e3 * cpu:.1f} ms of CPU in it '
        f'({100 * cpu / (cores * window.latency):.0f} % of {cores} cores)\n'
        'light: wall time of a call; dark: its CPU time (drawn from its start); '
        'v: an observation published, *: the estimate',
        fontsize=8,
    )
    ax.grid(axis='x', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_timeline(
    run_dir: Path, cores: int, rtf: float = 1.0, demands: Sequence[dict[str, Any]] | None = None
) -> Path | None:
    """``timeline.png`` (the demand of median latency) and ``timeline.json`` (every demand's
    latency, CPU in its window and occupancy) in ``run_dir`` from the traces in
    ``logs/callbacks`` of a run at ``rtf`` and its ``demands`` (default: its results.json);
    None when there is nothing to place (no traces, no estimates)."""
    traces = load_traces(run_dir / 'logs' / 'callbacks')
    results = run_dir / 'results.json'
    doc: dict[str, Any] = json.loads(results.read_text()) if results.is_file() else {}
    windows = demand_windows(doc.get('demands', []) if demands is None else demands, traces, rtf)
    if not windows:
        return None
    rows = summarise(windows, traces, cores)
    median = statistics.median_low([w.latency for w in windows])
    chosen = next(w for w in windows if w.latency == median)
    summary = {
        'cores': cores,
        'median_occupancy': statistics.median(r['occupancy'] for r in rows),
        'demands': rows,
    }
    (run_dir / 'timeline.json').write_text(json.dumps(summary, indent=1) + '\n')
    title = f'Set {doc.get("set", "A")} {doc.get("system", "fast")}' if doc else 'run'
    return plot_timeline(chosen, traces, run_dir / 'timeline.png', title, cores)
