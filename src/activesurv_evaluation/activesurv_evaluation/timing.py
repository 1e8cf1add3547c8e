"""Each demand's latency budget, from the times its messages reached the recorder.

A bag holds every message with the time the recorder received it (on the run's clock: the
simulated clock, interpolated between ``/clock`` ticks, or the wall clock on a rig). For each
demand, in seconds after its instant (``null`` where a step did not happen or its messages are
not in the bag):

* ``stage_state``: the last assigned camera's first stage state stamped at or after the
  instant (where the camera was when the frame was taken);
* ``frames``: when each camera's frame for the demand reached its imager (the observation's
  ``frame_received``, on the imager's clock, between ``/clock`` ticks on simulated time:
  :class:`activesurv_common.ros.fine_clock.FineClock`); for observations without it (older
  bags), when the recorder heard the frame stamped at the instant plus the observation's
  ``frame_offset``;
* ``observations``: each camera's marker observation, as its imager published it (the
  observation's ``published``, on the imager's fine clock as ``frame_received``); for older
  bags, when the recorder heard it;
* ``estimate``: the fused estimate as fusion published it (its ``published``, on fusion's
  fine clock; the demand's ``latency``); for older bags, when the recorder heard it;
* ``heard``: when the recorder heard each observation and the estimate (``observations``,
  ``estimate``): a listener's view, later than the producers' own by the hop and by the
  recorder's wake-up (it runs at a lower priority in simulated runs);
* ``compute``: each camera's imager's own processing of its frame (detect, fit, pose; from
  the observation's ``compute_time``; ``{}`` for bags from before it was carried);
* ``fusion_compute``: fusion's own processing from the message that completed the demand to
  the estimate (the estimate's ``compute_time``; ``null`` for bags from before it was carried).

:func:`critical_compute` is the compute on a demand's critical path: the slowest of its
cameras' processing (the cameras image in parallel, each on its own host on a rig) plus
fusion's. :func:`compute_on_cores` is the least time that compute can take on a host with
``cores`` cores, where every camera's imaging shares them: the k imagings take at least their
sum over the cores.

:func:`largest_wait` names the step that took longest after the one before it.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

STAMP_TOLERANCE = 2e-4  # s: a frame's stamp against instant + frame_offset


def _stamp(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


class _Arrivals:
    """(stamp, receive time) of one topic, sorted by stamp."""

    def __init__(self) -> None:
        self.stamps: list[float] = []
        self.received: list[float] = []

    def add(self, stamp: float, received: float) -> None:
        if self.stamps and stamp < self.stamps[-1]:
            i = bisect.bisect_right(self.stamps, stamp)
            self.stamps.insert(i, stamp)
            self.received.insert(i, received)
        else:
            self.stamps.append(stamp)
            self.received.append(received)

    def first_at_or_after(self, t: float) -> float | None:
        i = bisect.bisect_left(self.stamps, t - 1e-6)
        return self.received[i] if i < len(self.stamps) else None

    def stamped(self, t: float) -> float | None:
        i = bisect.bisect_left(self.stamps, t - STAMP_TOLERANCE)
        if i < len(self.stamps) and abs(self.stamps[i] - t) <= STAMP_TOLERANCE:
            return self.received[i]
        return None


def step_topics(cameras: Iterable[str]) -> set[str]:
    """The topics :class:`StepTimes` hears besides observations and estimates."""
    out: set[str] = set()
    for c in cameras:
        out |= {f'/{c}/stage/joint_states', f'/{c}/image_raw'}
    return out


class StepTimes:
    """Receive times of the stage states and frames of a run (see the module)."""

    def __init__(self) -> None:
        self._states: dict[str, _Arrivals] = {}
        self._frames: dict[str, _Arrivals] = {}

    def hear(self, topic: str, msg: Any, received: float) -> bool:
        """Note a stage state or frame; False for any other topic."""
        parts = topic.split('/')
        if topic.endswith('/stage/joint_states') and len(parts) == 4:
            self._states.setdefault(parts[1], _Arrivals()).add(_stamp(msg), received)
            return True
        if topic.endswith('/image_raw') and len(parts) == 3:
            self._frames.setdefault(parts[1], _Arrivals()).add(_stamp(msg), received)
            return True
        return False

    def timing(
        self,
        instant: float,
        assigned: Sequence[str],
        observations: Sequence[tuple[Any, float]],
        estimate_received: float | None,
        estimate_published: float | None = None,
        estimate_compute: float | None = None,
    ) -> dict[str, Any]:
        """The demand's budget: ``observations`` are (message, receive time) pairs;
        ``estimate_published``: the estimate's own ``published`` (s after the instant);
        ``estimate_compute``: its ``compute_time`` (s)."""
        states = [
            s.first_at_or_after(instant)
            for c in assigned
            if (s := self._states.get(c)) is not None
        ]
        frames: dict[str, float] = {}
        seen: dict[str, float] = {}
        heard: dict[str, float] = {}
        compute: dict[str, float] = {}
        for o, received in observations:
            cam = str(o.camera_id)
            heard.setdefault(cam, received - instant)
            told = published(o)
            seen.setdefault(cam, told if told is not None else received - instant)
            spent = float(getattr(o, 'compute_time', 0.0))
            if spent > 0.0:
                compute.setdefault(cam, spent)
            if int(o.status) == 3:  # no frame taken
                continue
            if math.isfinite(told := float(getattr(o, 'frame_received', math.nan))):
                frames[cam] = told  # the imager's own clock: when it had the frame
                continue
            arrivals = self._frames.get(cam)
            got = (
                None
                if arrivals is None
                else arrivals.stamped(instant + float(getattr(o, 'frame_offset', 0.0)))
            )
            if got is not None:
                frames[cam] = got - instant  # bags from before the imager said it
        known = [s for s in states if s is not None]
        got = None if estimate_received is None else estimate_received - instant
        return {
            'stage_state': max(known) - instant if known and len(known) == len(states) else None,
            'frames': frames,
            'observations': seen,
            'estimate': estimate_published if estimate_published is not None else got,
            'compute': compute,
            'fusion_compute': estimate_compute,
            'heard': {'observations': heard, 'estimate': got},
        }


def published(msg: Any, field: str = 'published') -> float | None:
    """A message's own ``published`` (or another of its times after its instant, such as an
    observation's ``frame_received``), in s; None where unknown (NaN, or older bags)."""
    v = float(getattr(msg, field, math.nan))
    return v if math.isfinite(v) else None


def empty_timing(latency: float | None = None) -> dict[str, Any]:
    """A demand's budget where nothing was recorded (lockstep: no messages)."""
    return {
        'stage_state': None,
        'frames': {},
        'observations': {},
        'estimate': latency,
        'compute': {},
        'fusion_compute': None,
        'heard': {'observations': {}, 'estimate': None},
    }


def critical_compute(timing: dict[str, Any]) -> float | None:
    """The slowest camera's processing of the demand's frame plus fusion's (s), or None if no
    camera's is known (fusion's counts as 0 where unknown: older bags)."""
    spent = (timing.get('compute') or {}).values()
    return max(spent) + float(timing.get('fusion_compute') or 0.0) if spent else None


def compute_on_cores(timing: dict[str, Any], cores: int) -> float | None:
    """The least time the demand's compute takes on ``cores`` cores shared by all its cameras'
    imaging (s): the slowest imaging or their sum over the cores, whichever is longer, plus
    fusion's; None if no camera's is known."""
    spent = list((timing.get('compute') or {}).values())
    if not spent or cores < 1:
        return None
    fusion = float(timing.get('fusion_compute') or 0.0)
    return max(float(max(spent)), float(sum(spent)) / cores) + fusion


def compute_unsplit(timing: dict[str, Any], cores: int) -> float | None:
    """The least time the demand's compute takes on ``cores`` cores when each camera's imaging
    runs on one core, as it does (one thread of its camera's process), s: the best assignment
    of the imagings to the cores, its busiest core's sum, plus fusion's. Three imagings of
    4 ms on two cores take 8 ms this way, against 6 ms (:func:`compute_on_cores`) were the
    work divisible. None if no camera's is known."""
    spent = sorted((float(v) for v in (timing.get('compute') or {}).values()), reverse=True)
    if not spent or cores < 1:
        return None
    fusion = float(timing.get('fusion_compute') or 0.0)
    if len(spent) <= cores:
        return spent[0] + fusion
    best = math.inf
    if cores ** (len(spent) - 1) <= 4096:  # every assignment (the first's core fixed)
        for ways in itertools.product(range(cores), repeat=len(spent) - 1):
            load = [0.0] * cores
            load[0] = spent[0]
            for c, v in zip(ways, spent[1:], strict=True):
                load[c] += v
            best = min(best, max(load))
    else:  # longest first onto the least loaded core (within 4/3 of the best)
        load = [0.0] * cores
        for v in spent:
            load[load.index(min(load))] += v
        best = max(load)
    return best + fusion


def camera_delays(demands: Iterable[dict[str, Any]]) -> list[float]:
    """Each frame's arrival at its imager after its exposure (s): a camera's own delay as the
    host sees it (exposure, read-out, transfer: ``timing.frames`` minus ``frame_offsets``, per
    camera of every demand of a ``results.json``)."""
    out = []
    for d in demands:
        offsets = d.get('frame_offsets') or {}
        for cam, got in ((d.get('timing') or {}).get('frames') or {}).items():
            if got is not None and offsets.get(cam) is not None:
                out.append(float(got) - float(offsets[cam]))
    return out


def frames_bound(demand: dict[str, Any]) -> float | None:
    """A demand's own bound (s after its instant): its last frame's arrival at its imager plus
    the compute on its critical path, or None where either is unknown. It holds each camera's
    own delay and exposure offset for this demand, where a bound from the median delay does not
    (the estimate waits for the slowest of its cameras). A frame taken because a nearer one
    never came is counted at its own arrival, though the imager had to wait for the next one:
    that wait stays in the latency above this bound."""
    timing = demand.get('timing') or {}
    frames = [float(v) for v in (timing.get('frames') or {}).values() if v is not None]
    spent = critical_compute(timing)
    return max(frames) + spent if frames and spent is not None else None


STEPS = ('stage_state', 'frames', 'observations', 'estimate')


def budget(timing: dict[str, Any]) -> list[tuple[str, float]]:
    """The budget as consecutive segments (name, s): until the stage state, the last frame,
    the last observation, the estimate; each from the end of the one before (a step that did
    not happen is skipped)."""
    marks = [
        ('stage state', timing.get('stage_state')),
        ('frames', max(timing['frames'].values()) if timing.get('frames') else None),
        (
            'observations',
            max(timing['observations'].values()) if timing.get('observations') else None,
        ),
        ('fusion', timing.get('estimate')),
    ]
    out = []
    before = 0.0
    for name, t in marks:
        if t is None:
            continue
        out.append((name, max(0.0, float(t) - before)))
        before = max(before, float(t))
    return out


def largest_wait(timings: Iterable[dict[str, Any]]) -> tuple[str, float] | None:
    """The segment with the largest median over the demands (name, median s)."""
    from statistics import median

    rows: dict[str, list[float]] = {}
    for t in timings:
        for name, seg in budget(t):
            rows.setdefault(name, []).append(seg)
    if not rows:
        return None
    name = max(rows, key=lambda n: median(rows[n]))
    return name, median(rows[name])


SEGMENT_COLOURS = {
    'stage state': '#8da0cb',
    'frames': '#66c2a5',
    'observations': '#fc8d62',
    'fusion': '#e78ac3',
}


def plot_budget(
    rows: Sequence[dict[str, Any]], path: Path, title: str, cores: int | None = None
) -> Path | None:
    """A stacked bar per demand (ms after its instant): until the stage state, the frames,
    the observations, the estimate (``rows``: results.json demands), and a black line at the
    demand's compute on the critical path (:func:`critical_compute`), the least it could take.
    With ``cores``, a dashed line where its cameras' imagings outnumber them: the least the
    same compute takes with each imaging on one core (:func:`compute_unsplit`).
    Returns ``path``, or None when no demand has a timing."""
    # matplotlib (heavy) only when a figure is drawn
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    timed = [r for r in rows if r.get('timing') and budget(r['timing'])]
    if not timed:
        return None
    bars = [(int(r['index']), budget(r['timing']), critical_compute(r['timing'])) for r in timed]
    unsplit = [
        compute_unsplit(r['timing'], cores)
        if cores and len(r['timing'].get('compute') or {}) > cores
        else None
        for r in timed
    ]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.25 * len(bars) + 2.0), 3.4))
    shown: set[str] = set()
    for x, (_, segments, compute) in enumerate(bars):
        bottom = 0.0
        for name, seg in segments:
            label = None if name in shown else name
            shown.add(name)
            ax.bar(x, 1e3 * seg, bottom=bottom, color=SEGMENT_COLOURS[name], label=label)
            bottom += 1e3 * seg
        if compute is not None:
            label = None if 'compute' in shown else 'compute on the critical path'
            shown.add('compute')
            ax.plot([x - 0.4, x + 0.4], [1e3 * compute] * 2, color='k', lw=1.5, label=label)
        if unsplit[x] is not None:
            label = (
                None if 'unsplit' in shown else f'the same, each imaging on one of {cores} cores'
            )
            shown.add('unsplit')
            level = [1e3 * float(unsplit[x] or 0.0)] * 2
            ax.plot([x - 0.4, x + 0.4], level, color='k', lw=1.2, ls='--', label=label)
    top = max(1e3 * sum(seg for _, seg in segments) for _, segments, _ in bars)
    ax.set_ylim(0.0, 1.3 * top if top > 0.0 else 1.0)  # room for the legend
    ax.set_xticks(range(len(bars)))
    ax.set_xticklabels(
        [str(j) if len(bars) <= 40 or i % 10 == 0 else '' for i, (j, _, _) in enumerate(bars)],
        fontsize=7,
    )
    ax.set_xlabel('demand')
    ax.set_ylabel('ms after the instant')
    wait = largest_wait(r['timing'] for r in rows if r.get('timing'))
    ax.set_title(
        title
        + ('' if wait is None else f' (largest wait: {wait[0]}, median {1e3 * wait[1]:.1f} ms)'),
        fontsize=9,
    )
    ax.legend(fontsize=7, ncol=3, loc='upper left')
    ax.grid(axis='y', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
