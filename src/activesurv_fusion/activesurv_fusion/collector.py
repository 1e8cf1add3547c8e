"""Collect the observations of each demand instant and decide when to fuse (pure core).

A demand is *opened* by a capture request (the cameras assigned to it) or, if the request was
missed (for example after a restart of the fusion node), by its first observation. It is *ready*
when every assigned camera has answered, or when its deadline has passed. Every opened demand is
eventually returned by :meth:`DemandCollector.pop_ready` exactly once, so no demand is left
without an answer. Late observations of a demand already answered are counted and dropped.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike

from activesurv_common.information import covariance_visibility
from activesurv_common.statuses import DemandStatus
from activesurv_fusion.errors import InvalidReadingError, NoConsensusError
from activesurv_fusion.pose_fusion import FusedPose, PoseReading, fuse_poses


class Outcome(Enum):
    """How one camera answered."""

    OK = 'ok'
    FAILED = 'failed'  # the camera answered with a failure status (marker not found, ...)


@dataclass
class Answer:
    camera_id: str
    outcome: Outcome
    reading: PoseReading | None
    reason: str = ''


def camera_answer(
    camera_id: str,
    ok: bool,
    position: ArrayLike | None,
    normal: ArrayLike | None,
    covariance: ArrayLike | None,
    reason: str,
) -> Answer:
    """A camera's answer to a demand from its observation (the node's message and lockstep's
    observation alike): a failed one keeps the imager's reason; an OK one that is not a valid
    reading becomes a failed answer that says why."""
    if not ok or position is None or normal is None or covariance is None:
        return Answer(camera_id, Outcome.FAILED, None, reason)
    try:
        reading = PoseReading.create(camera_id, position, normal, np.asarray(covariance))
    except InvalidReadingError as exc:
        return Answer(camera_id, Outcome.FAILED, None, f'invalid observation: {exc}')
    return Answer(camera_id, Outcome.OK, reading)


@dataclass
class DemandBatch:
    """Everything known about one demand when it is handed to fusion."""

    index: int
    demand_time: float
    assigned: tuple[str, ...]
    answers: dict[str, Answer] = field(default_factory=dict)
    deadline: float = math.inf
    prior_normal: tuple[float, float, float] | None = None

    @property
    def missing(self) -> tuple[str, ...]:
        return tuple(c for c in self.assigned if c not in self.answers)

    @property
    def readings(self) -> list[PoseReading]:
        return [a.reading for a in self.answers.values() if a.reading is not None]

    def complete(self) -> bool:
        return bool(self.assigned) and not self.missing


class DemandCollector:
    """Tracks open demands; times are seconds on the node's clock (sim time in experiments)."""

    def __init__(self, timeout: float, orphan_timeout: float | None = None) -> None:
        """Args:
        timeout: seconds after a demand instant (or its request, whichever is later) after
            which the demand is fused with whatever arrived.
        orphan_timeout: the same for a demand opened by an observation alone; defaults to
            ``timeout``.
        """
        if not (math.isfinite(timeout) and timeout > 0.0):
            raise InvalidReadingError(f'timeout must be finite and > 0, got {timeout}')
        self._timeout = timeout
        self._orphan_timeout = timeout if orphan_timeout is None else orphan_timeout
        self._open: dict[int, DemandBatch] = {}
        self._closed: set[int] = set()
        self.late_observations = 0

    def set_timeout(self, timeout: float) -> None:
        """Change the timeout of demands opened from now on."""
        if not (math.isfinite(timeout) and timeout > 0.0):
            raise InvalidReadingError(f'timeout must be finite and > 0, got {timeout}')
        self._timeout = timeout

    @property
    def open_indices(self) -> tuple[int, ...]:
        return tuple(sorted(self._open))

    def is_closed(self, index: int) -> bool:
        return index in self._closed

    def mark_answered(self, indices: Iterable[int]) -> None:
        """Demands answered elsewhere (by this node before a restart): never answer them again."""
        for i in indices:
            self._closed.add(int(i))
            self._open.pop(int(i), None)

    def request(
        self,
        index: int,
        demand_time: float,
        cameras: tuple[str, ...],
        now: float,
        prior_normal: tuple[float, float, float] | None = None,
    ) -> bool:
        """Open (or complete the description of) a demand. Returns False if it was answered."""
        if index in self._closed:
            return False
        deadline = max(demand_time, now) + self._timeout
        batch = self._open.get(index)
        if batch is None:
            self._open[index] = DemandBatch(
                index, demand_time, tuple(cameras), deadline=deadline, prior_normal=prior_normal
            )
        else:
            batch.assigned = tuple(cameras)
            batch.demand_time = demand_time
            batch.deadline = deadline
            batch.prior_normal = prior_normal
        return True

    def observe(self, index: int, answer: Answer, now: float, demand_time: float) -> bool:
        """Record one camera's answer. Returns False (and counts it) if the demand was answered."""
        if index in self._closed:
            self.late_observations += 1
            return False
        batch = self._open.get(index)
        if batch is None:
            batch = DemandBatch(
                index, demand_time, (), deadline=max(demand_time, now) + self._orphan_timeout
            )
            self._open[index] = batch
        batch.answers[answer.camera_id] = answer
        return True

    def deadlines(self) -> set[float]:
        """The deadlines of the open demands (a caller's timers decide them then)."""
        return {b.deadline for b in self._open.values() if math.isfinite(b.deadline)}

    def pop_ready(self, now: float) -> list[DemandBatch]:
        """Remove and return the demands that are complete or past their deadline, oldest first."""
        ready = [b for b in self._open.values() if b.complete() or now >= b.deadline]
        ready.sort(key=lambda b: b.index)
        for b in ready:
            del self._open[b.index]
            self._closed.add(b.index)
        return ready

    def flush(self) -> list[DemandBatch]:
        """Remove and return every open demand (on shutdown: answer them rather than drop them)."""
        return self.pop_ready(math.inf)


@dataclass(frozen=True)
class DemandResult:
    """The answer for one demand: a fused pose or an explicit failure."""

    index: int
    demand_time: float
    status: DemandStatus
    reason: str
    fused: FusedPose | None
    cameras_missing: tuple[str, ...]
    cameras_failed: tuple[str, ...]

    @property
    def fused_visibility(self) -> float:
        """v_f = 1 / ||P||_F of the cameras used (eq. 2); 0 without an estimate."""
        if self.fused is None:
            return 0.0
        return covariance_visibility(self.fused.covariance)


def resolve(batch: DemandBatch, z: float = 3.0, max_faulty: int | None = None) -> DemandResult:
    """Fuse a ready batch, or say why it cannot be fused."""
    failed = tuple(sorted(a.camera_id for a in batch.answers.values() if a.reading is None))
    missing = batch.missing
    readings = sorted(batch.readings, key=lambda r: r.camera_id)
    notes = []
    if missing:
        notes.append(f'no answer from {", ".join(missing)}')
    if failed:
        notes.append(
            'failed: '
            + '; '.join(f'{c} ({batch.answers[c].reason or "no reason"})' for c in failed)
        )
    if not readings:
        if not batch.assigned and not batch.answers:
            notes.append('no camera was assigned to this demand')
        reason = 'no usable observation' + (': ' + '; '.join(notes) if notes else '')
        return DemandResult(
            batch.index,
            batch.demand_time,
            DemandStatus.NO_OBSERVATIONS,
            reason,
            None,
            missing,
            failed,
        )
    try:
        fused = fuse_poses(readings, z=z, max_faulty=max_faulty)
    except NoConsensusError as exc:
        return DemandResult(
            batch.index,
            batch.demand_time,
            DemandStatus.NO_CONSENSUS,
            str(exc),
            None,
            missing,
            failed,
        )
    status = DemandStatus.PARTIAL if (missing or failed) else DemandStatus.OK
    if fused.cameras_faulty:
        notes.append(f'faulty: {", ".join(fused.cameras_faulty)}')
    return DemandResult(
        batch.index, batch.demand_time, status, '; '.join(notes), fused, missing, failed
    )
