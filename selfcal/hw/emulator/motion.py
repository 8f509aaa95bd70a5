"""The emulated arm's motion, in encoder counts and controller time.

A motion is a segment from the counts at rest to a target, interpolated linearly in time; its
duration follows from the slowest joint at ``move_speed_deg_s`` x SPEED / 50 (or is given). MOVEs
sent while the arm moves queue up. Events (an injected impact, a disconnect, a late message) are
scheduled at their own times; ``_advance(now)`` processes them and the segment ends in time order,
so a late tick of the clock changes nothing. Whenever the arm comes to rest the backend is told
where (``EmulatorBackend.set_joints_deg``).

``selfcal.hw.emulator.controller.AclController`` builds the ACL dialogue on this; it acts on three hooks:
``_rested`` (the arm came to rest), ``_homing_complete`` and ``_impacted``.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from selfcal.hw.emulator.backends import EmulatorBackend
from selfcal.hw.emulator.faults import Fault
from selfcal.hw.emulator.transport import Terminal
from selfcal.hw.encoders import EncoderTable

__all__ = ["Segment", "ArmMotion"]


@dataclass
class Segment:
    """One motion: ``start`` to ``target`` counts from time ``t0`` to ``t1``."""

    start: np.ndarray
    target: np.ndarray
    t0: float
    t1: float
    kind: str  # "move" | "home"
    session: Terminal | None = None
    impact: Fault | None = None

    def counts_at(self, now: float) -> np.ndarray:
        if self.t1 <= self.t0:
            return self.target.copy()
        s = min(max((now - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return np.rint(self.start + (self.target - self.start) * s).astype(np.int64)


class ArmMotion:
    """The arm of an emulated controller: encoder counts, the current segment, the MOVE queue and
    the scheduled events, all changed under ``_lock``.

    Args:
        backend: the arm behind the controller (told where it comes to rest).
        encoders: counts <-> degrees.
        move_speed_deg_s: joint speed (deg/s) of the slowest-finishing joint at SPEED 50.
    """

    def __init__(
        self, backend: EmulatorBackend, encoders: EncoderTable, move_speed_deg_s: float
    ) -> None:
        self.backend = backend
        self.encoders = encoders
        self.n = encoders.n
        self.move_speed_deg_s = float(move_speed_deg_s)
        self._lock = threading.RLock()
        self._counts = encoders.home_counts.copy()
        self._segment: Segment | None = None
        self._queue: deque[tuple[np.ndarray, float | None, Fault | None]] = deque()
        self._speed = 50
        self._homed = False
        self._scheduled: list[tuple[float, Callable[[], None]]] = []

    # -- state ---------------------------------------------------------------------------------

    def counts(self) -> np.ndarray:
        """Current encoder counts (n,)."""
        with self._lock:
            self._advance(time.monotonic())
            return self._current_counts(time.monotonic())

    def joints_deg(self) -> np.ndarray:
        """Current joint angles (deg) from the counts."""
        return self.encoders.to_degrees(self.counts())

    @property
    def moving(self) -> bool:
        with self._lock:
            self._advance(time.monotonic())
            return self._segment is not None

    def wait_until_still(self, timeout_s: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if not self.moving:
                return True
            time.sleep(0.005)
        return False

    # -- hooks ---------------------------------------------------------------------------------

    def _rested(self) -> None:
        """The arm has come to rest and the backend knows it."""

    def _homing_complete(self, seg: Segment) -> None:
        """The HOME segment ``seg`` has ended."""

    def _impacted(self, axis: int) -> None:
        """An injected impact on ``axis`` has stopped the arm."""

    # -- motion --------------------------------------------------------------------------------

    def _current_counts(self, now: float) -> np.ndarray:
        if self._segment is not None:
            return self._segment.counts_at(now)
        return self._counts.copy()

    def _duration(self, start: np.ndarray, target: np.ndarray) -> float:
        dq = np.abs(self.encoders.to_degrees(target) - self.encoders.to_degrees(start))
        speed = self.move_speed_deg_s * self._speed / 50.0
        return float(np.max(dq) / speed) if dq.size else 0.0

    def _start_segment(
        self,
        target: np.ndarray,
        duration: float | None,
        kind: str,
        t0: float,
        session: Terminal | None = None,
        impact: Fault | None = None,
    ) -> None:
        start = self._counts.copy()
        dur = self._duration(start, target) if duration is None else float(duration)
        seg = Segment(start, target.astype(np.int64), t0, t0 + dur, kind, session, impact)
        self._segment = seg
        if impact is not None:
            t_hit = seg.t0 + impact.at_fraction * (seg.t1 - seg.t0)
            self._scheduled.append((t_hit, lambda: self._impact(seg, impact.axis, t_hit)))

    def _advance(self, now: float) -> None:
        """Bring the controller to time ``now``: scheduled events (impact, disconnect, ...) and
        segment ends are processed in time order, each at its own time, so a late tick of the
        clock thread changes nothing."""
        while True:
            seg_end = self._segment.t1 if self._segment is not None else float("inf")
            due = [ev for ev in self._scheduled if ev[0] <= now]
            first = min(due, key=lambda ev: ev[0]) if due else None
            if first is not None and first[0] <= seg_end:
                self._scheduled.remove(first)
                first[1]()
                continue
            if self._segment is not None and now >= seg_end:
                self._finish_segment()
                continue
            return

    def _finish_segment(self) -> None:
        seg = self._segment
        assert seg is not None
        self._segment = None
        self._counts = seg.target.copy()
        self._arrive()
        if seg.kind == "home":
            self._homed = True
            self._homing_complete(seg)
        if self._queue:
            target, dur, impact = self._queue.popleft()
            self._start_segment(target, dur, "move", seg.t1, impact=impact)

    def _arrive(self) -> None:
        """The arm is at rest at ``self._counts``: tell the backend (and ``_rested``)."""
        q = self.encoders.to_degrees(self._counts)
        reported = self.backend.set_joints_deg(q)
        if reported is not None:
            self._counts = self.encoders.to_counts(
                np.asarray(reported, dtype=float).reshape(self.n)
            )
        self._rested()

    def _stop_motion(self, at: float | None = None) -> str | None:
        """Stop wherever the arm is (at time ``at``, default now); returns the kind of the
        interrupted segment."""
        now = time.monotonic() if at is None else at
        kind = None
        if self._segment is not None:
            kind = self._segment.kind
            self._counts = self._segment.counts_at(now)
            self._segment = None
            self._arrive()
        self._queue.clear()
        return kind

    def _impact(self, seg: Segment, axis: int, t_hit: float) -> None:
        if self._segment is not seg:
            return  # that motion already ended or was aborted
        self._stop_motion(at=t_hit)
        self._impacted(axis)
