"""A session's report: one line per object, the error and latency of every demand over time,
and the table from above with every object's demand points and the cell's obstacles."""

from __future__ import annotations

import os
import statistics
from pathlib import Path
from typing import Any

import numpy as np

from activesurv_evaluation.timing import largest_wait, plot_budget


def session_table(doc: dict[str, Any]) -> str:
    """One line per object: path kind, entry/exit, demands, ok, median errors and latency."""
    head = (
        f'{"object":>6} {"path":>13} {"entered [s]":>11} {"left [s]":>9} {"demands":>7} '
        f'{"ok":>4} {"pos err [mm]":>12} {"latency [ms]":>12}'
    )
    lines = [head, '-' * len(head)]
    rows = list(doc['objects']) + [{'id': None}]
    for o in rows:
        ds = [d for d in doc['demands'] if o['id'] is None or d['object'] == o['id']]
        ok = [d for d in ds if d['status'] == 'ok']
        err = [d['position_error'] for d in ok if d['position_error'] is not None]
        lat = [d['latency'] for d in ds if d.get('latency') is not None]

        def num(v: float | None, w: int, scale: float = 1.0, fmt: str = '.3f') -> str:
            return f'{"-":>{w}}' if v is None else f'{v * scale:>{w}{fmt}}'

        med_err = statistics.median(err) if err else None
        med_lat = statistics.median(lat) if lat else None
        if o['id'] is None:
            lines.append('-' * len(head))
            name, kind, entered, left = 'all', '', None, None
        else:
            name, kind, entered, left = str(o['id']), str(o['path_kind']), o['entered'], o['left']
        lines.append(
            f'{name:>6} {kind:>13} {num(entered, 11, fmt=".1f")} {num(left, 9, fmt=".1f")} '
            f'{len(ds):>7} {len(ok):>4} {num(med_err, 12, 1e3)} {num(med_lat, 12, 1e3, ".0f")}'
        )
    return '\n'.join(lines)


def _top_view(doc: dict[str, Any], path: Path) -> Path:
    """The table from above: every object's demand points (true, and the estimates), each
    object in its colour, failed demands marked, and the cell's obstacles."""
    # matplotlib (heavy) only when a figure is drawn
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.add_patch(Rectangle((0.0, 0.0), 0.5, 0.2, fill=False, lw=1.0, color='0.4'))
    for o in doc.get('obstacles') or []:
        c = o['centre']
        if o['kind'] == 'box':
            dx, dy = o['size'][0], o['size'][1]
            ax.add_patch(Rectangle((c[0] - dx / 2, c[1] - dy / 2), dx, dy, color='0.5'))
        else:
            ax.add_patch(Circle((c[0], c[1]), o['radius'], color='0.5'))
    for o in doc['objects']:
        ds = sorted((d for d in doc['demands'] if d['object'] == o['id']), key=lambda d: d['t'])
        xy = np.array([d['true_position'][:2] for d in ds if d.get('true_position')])
        if len(xy) == 0:
            continue
        (line,) = ax.plot(xy[:, 0], xy[:, 1], '-o', ms=3, lw=1, label=f'object {o["id"]}')
        est = np.array([d['estimated_position'][:2] for d in ds if d.get('estimated_position')])
        if len(est):
            ax.plot(est[:, 0], est[:, 1], 'x', ms=4, color=line.get_color())
        bad = np.array(
            [d['true_position'][:2] for d in ds if d['status'] != 'ok' and d.get('true_position')]
        )
        if len(bad):
            ax.plot(bad[:, 0], bad[:, 1], 'o', ms=9, mfc='none', color='red')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m] (cameras below, at y < 0)')
    low = [o['centre'][1] - 0.05 for o in doc.get('obstacles') or []]
    ax.set_ylim(min([-0.05, *low]), 0.22)
    ax.grid(alpha=0.3)
    if doc['objects']:
        ax.legend(fontsize=7, ncol=4, loc='lower left')
    ax.set_title('demand points (o), estimates (x), failed (red), obstacles (grey)', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_surveil_report(doc: dict[str, Any], out_dir: Path) -> Path:
    """``report.md`` and ``session.png`` (error and latency of every demand over time)."""
    # matplotlib (heavy) only when a figure is drawn
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for o in doc['objects']:
        ds = [d for d in doc['demands'] if d['object'] == o['id']]
        ts = [d['t'] for d in ds]
        err = [np.nan if d['position_error'] is None else 1e3 * d['position_error'] for d in ds]
        lat = [np.nan if d.get('latency') is None else 1e3 * d['latency'] for d in ds]
        label = f'object {o["id"]} ({o["path_kind"]})'
        axes[0].plot(ts, err, 'o', ms=4, label=label)
        axes[1].plot(ts, lat, 'o', ms=4)
    axes[0].set_ylabel('position error [mm]')
    axes[1].set_ylabel('latency [ms]')
    axes[1].set_xlabel('simulated time [s]')
    for ax in axes:
        ax.grid(alpha=0.3)
    if doc['objects']:
        axes[0].legend(fontsize=7, ncol=3)
    fig.tight_layout()
    png = out_dir / 'session.png'
    fig.savefig(png, dpi=90)
    plt.close(fig)
    top = _top_view(doc, out_dir / 'scene_top.png')
    budget_png = plot_budget(
        doc['demands'], out_dir / 'latency.png', 'latency budget', len(os.sched_getaffinity(0))
    )
    wait = largest_wait(d['timing'] for d in doc['demands'] if d.get('timing'))
    s = doc['summary']
    title = f'Set {doc["set"]}' if doc.get('set') else 'continuous surveillance'
    gospa = s.get('gospa_mean')
    blocked = sum(1 for d in doc['demands'] if d.get('occluded'))
    n_obstacles = len(doc.get('obstacles') or [])
    lines = [
        f'# activesurv {title}',
        '',
        f'{s["objects"]} objects, {s["demands"]} demands ({doc["demand_mode"]}), '
        f'{s["ok"]} ok, over {doc["simulated_seconds"]:.0f} s of simulated time; '
        f'system {doc["system"]}, seed {doc["seed"]}; '
        + (
            f'{n_obstacles} obstacle{"" if n_obstacles == 1 else "s"}'
            if n_obstacles
            else 'no obstacle'
        )
        + ' in the cell.',
        '',
        f'Overhead tracking: at most {s.get("max_objects_at_once")} objects at once, '
        f'{s.get("id_switches")} id switches, GOSPA mean '
        + ('-' if gospa is None else f'{1e3 * gospa:.2f} mm')
        + f'. Demands with an assigned camera whose view was blocked at the instant: {blocked}.',
        '',
        'Failed demands:',
        '',
    ]
    failed = [d for d in doc['demands'] if d['status'] != 'ok']
    lines += [
        f'- demand {d["index"]} (object {d["object"]}): {d["status"]}: {d["reason"]}'
        for d in failed
    ] or ['- none']
    lines += ['', '```', session_table(doc), '```', '', f'![session]({png.name})', '']
    lines += [f'![objects and obstacles seen from above]({top.name})', '']
    if budget_png is not None and wait is not None:
        lines += [
            f'Latency budget per demand; the largest wait is {wait[0]} (median '
            f'{1e3 * wait[1]:.1f} ms after the step before it).',
            '',
            f'![latency budget]({budget_png.name})',
            '',
        ]
    path = out_dir / 'report.md'
    path.write_text('\n'.join(lines))
    return path
