"""How well the overhead tracks follow the objects: GOSPA and identity switches.

The overhead tracks (``object_tracks``: each track's filtered position at each overhead fix)
are compared with the truth (the objects' top markers, present while on the table) at the
tracks' own instants:

* ``gospa_mean`` (m): the generalised optimal sub-pattern assignment metric (Rahmathullah,
  Garcia-Fernandez, Svensson 2017; alpha = 2, p = 1, cut-off ``c`` = 50 mm, with a switching
  penalty of ``c`` / 2), averaged over the instants, from Stone Soup's ``GOSPAMetric``: a
  position error of each assigned pair, ``c`` / 2 for each missed object or false track;
* ``id_switches``: how often an object's track identity (the id its demands carry) changed
  while it was tracked, objects and confirmed tracks paired one to one each frame (least total
  distance, within 15 mm);
* ``max_objects_at_once``: the most objects on the table at one instant.

Tentative tracks (no id yet) count as tracks for GOSPA, not for identities.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

CUTOFF = 0.05  # m: GOSPA's c
ID_GATE = 0.015  # m: an object and a track further apart are not paired for identities
EPOCH = dt.datetime(2000, 1, 1)


@dataclass(frozen=True)
class Snapshot:
    """Objects (truth) or tracks at one instant: (id, x, y) each."""

    t: float
    items: tuple[tuple[int, float, float], ...]


def track_metrics(tracks: Sequence[Snapshot], truth: Sequence[Snapshot]) -> dict[str, Any]:
    """GOSPA mean, identity switches and the most objects at once (see the module).

    ``truth`` is taken at the same instants as ``tracks`` (one snapshot each, same order);
    with no truth (a hardware run without a table controller) GOSPA and switches are None.
    """
    most = max((len(s.items) for s in truth), default=0)
    if not truth or not tracks:
        return {'max_objects_at_once': most or None, 'id_switches': None, 'gospa_mean': None}
    return {
        'max_objects_at_once': most,
        'id_switches': id_switches(tracks, truth),
        'gospa_mean': gospa_mean(tracks, truth),
    }


def gospa_mean(tracks: Sequence[Snapshot], truth: Sequence[Snapshot]) -> float:
    """Mean GOSPA (m) over the instants, from Stone Soup (imported here: it is heavy)."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric
    from stonesoup.types.state import State

    metric = GOSPAMetric(
        c=CUTOFF, p=1, measure=Euclidean(mapping=(0, 1)), switching_penalty=CUTOFF / 2
    )
    measured, measured_ids, truths, truth_ids = [], [], [], []
    fresh = -1  # a tentative track has no id: each is its own
    for snap_m, snap_t in zip(tracks, truth, strict=True):
        when = EPOCH + dt.timedelta(seconds=snap_m.t)
        for i, x, y in snap_m.items:
            measured.append(State(np.array([[x], [y]]), timestamp=when))
            if i == 0:
                fresh -= 1
            measured_ids.append(i if i != 0 else fresh)
        for i, x, y in snap_t.items:
            truths.append(State(np.array([[x], [y]]), timestamp=when))
            truth_ids.append(i)
    if not measured and not truths:
        return 0.0
    result = metric.compute_over_time(measured, measured_ids, truths, truth_ids)
    values = [float(m.value['distance']) for m in result.value]
    return float(np.mean(values)) if values else 0.0


def id_switches(tracks: Sequence[Snapshot], truth: Sequence[Snapshot]) -> int:
    """Changes of the confirmed track paired with each object: each frame, objects and
    confirmed tracks are paired one to one by least total distance (within ``ID_GATE``: half
    the 30 mm that objects at once keep apart), and a pairing that differs from the object's
    last one is a switch."""
    last: dict[int, int] = {}
    switches = 0
    for snap_m, snap_t in zip(tracks, truth, strict=True):
        confirmed = [(i, x, y) for i, x, y in snap_m.items if i != 0]
        if not confirmed or not snap_t.items:
            continue
        cost = np.array(
            [
                [float(np.hypot(x - tx, y - ty)) for _, tx, ty in confirmed]
                for _, x, y in snap_t.items
            ]
        )
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows, cols, strict=True):
            if cost[r, c] > ID_GATE:
                continue
            oid, tid = snap_t.items[r][0], confirmed[c][0]
            if oid in last and last[oid] != tid:
                switches += 1
            last[oid] = tid
    return switches


class TrackRecorder:
    """Collects overhead tracks and the truth from a bag's messages, for :func:`track_metrics`.

    Feed it ``/object_state`` (:meth:`on_truth`, one per lane with several objects at once)
    and ``/object_tracks`` (:meth:`on_tracks`) messages in any order; :meth:`metrics` matches
    each track message with every lane's truth at its stamp (held up to 0.5 s).
    """

    def __init__(self, truth_id: Callable[[float], int] | None = None) -> None:
        """``truth_id(t)``: the object's id at ``t`` for bags whose states carry none."""
        self.truth_id = truth_id
        # slot -> [(t, truth id, x, y, present)]
        self.truth: dict[int, list[tuple[float, int, float, float, bool]]] = {}
        self.tracks: list[tuple[float, tuple[tuple[int, float, float], ...]]] = []

    def on_truth(self, t: float, msg: Any) -> None:
        p = msg.top_marker
        slot = int(getattr(msg, 'slot', 0))
        oid = int(getattr(msg, 'id', 0))
        if not oid:  # a bag from before ids: the stream's (or the experiment's one object)
            oid = self.truth_id(t) if self.truth_id is not None else 1
        rows = self.truth.setdefault(slot, [])
        rows.append((t, oid, float(p.x), float(p.y), bool(msg.in_workspace)))

    def on_tracks(self, t: float, msg: Any) -> None:
        items = tuple((int(k.id), float(k.position.x), float(k.position.y)) for k in msg.tracks)
        self.tracks.append((t, items))

    def objects_at(self, t: float) -> list[tuple[int, float, float]]:
        """Every lane's object present at ``t`` (id, x, y), from the samples nearest ``t``."""
        out = []
        for rows in self.truth.values():
            times = np.array([r[0] for r in rows])
            j = int(np.searchsorted(times, t))
            near = [i for i in (j - 1, j) if 0 <= i < len(times)]
            if not near:
                continue
            i = min(near, key=lambda i: abs(times[i] - t))
            _, oid, x, y, present = rows[i]
            if abs(times[i] - t) <= 0.5 and present:
                out.append((oid, x, y))
        return out

    def metrics(self) -> dict[str, Any]:
        if not self.truth:
            return track_metrics([], [])
        for rows in self.truth.values():
            rows.sort()
        pairs_m = [Snapshot(t, items) for t, items in sorted(self.tracks)]
        pairs_t = [Snapshot(s.t, tuple(self.objects_at(s.t))) for s in pairs_m]
        out = track_metrics(pairs_m, pairs_t)
        stamps = sorted({r[0] for rows in self.truth.values() for r in rows})
        present: dict[float, int] = {}
        for rows in self.truth.values():
            for t, _, _, _, here in rows:
                present[t] = present.get(t, 0) + int(here)
        out['max_objects_at_once'] = max((present.get(t, 0) for t in stamps), default=0)
        return out
