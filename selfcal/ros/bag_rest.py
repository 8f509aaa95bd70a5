"""When was the arm at rest? Joint readings of a bag by time, interpolated at image stamps, and the
rest test of ``selfcal import --bag``.

An image is at rest when, over a window centred on its stamp, every joint's readings spread by at
most ``speed x window`` (a speed threshold over the window, robust to encoder noise) and the joint
messages cover the window with no gap longer than ``max_gap``. Stamps are integer nanoseconds;
joints SI (rad, m).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "RestRule",
    "JointTrack",
    "REST",
    "MOVING",
    "GAP",
    "OUTSIDE",
    "EMPTY",
    "NS",
    "pair_frames",
    "thin_rests",
]

REST, MOVING, GAP, OUTSIDE, EMPTY = "rest", "moving", "gap", "outside", "empty"
"""What :meth:`JointTrack.status` says of an image: at rest; moving; a gap in the joint messages
within the window; the window not covered by the joint recording (its start or end); no joint
message at all within the window although the stamp lies inside the recording."""
NS = 1_000_000_000
"""Nanoseconds per second: ROS stamps are integer ns (``sec * NS + nanosec``)."""


@dataclass(frozen=True)
class RestRule:
    """The rest test: ``window_s`` (s, centred on the image stamp), ``speed_rad_s`` (rad/s of a
    revolute joint), ``speed_m_s`` (m/s of a prismatic joint), ``max_gap_s`` (s between joint
    messages)."""

    window_s: float = 0.5
    speed_rad_s: float = float(np.radians(0.3))
    speed_m_s: float = 0.3e-3
    max_gap_s: float = 0.05

    def to_json(self) -> dict:
        """The rule at the file edge: s, deg/s (mm/s for a prismatic joint)."""
        return {"window_s": self.window_s, "speed_deg_s": float(np.degrees(self.speed_rad_s)),
                "speed_mm_s": float(self.speed_m_s * 1e3), "max_gap_s": self.max_gap_s}  # fmt: skip

    def describe(self) -> str:
        """The rule in words (s, deg/s)."""
        return (f"{self.window_s:g} s window, {np.degrees(self.speed_rad_s):g} deg/s, pauses up "
                f"to {self.max_gap_s:g} s")  # fmt: skip


class JointTrack:
    """Joint readings ``q`` (m, n) at stamps ``t`` (m,) int ns, sorted by stamp (a repeated stamp
    keeps its last reading); ``joint_types`` gives each joint's speed threshold."""

    def __init__(self, t: np.ndarray, q: np.ndarray, joint_types: tuple[str, ...]) -> None:
        t = np.asarray(t, np.int64)
        q = np.asarray(q, float)
        order = np.argsort(t, kind="stable")
        t, q = t[order], q[order]
        last = np.append(t[1:] != t[:-1], True)
        self.t, self.q = t[last], q[last]
        self._prismatic = np.array([j == "prismatic" for j in joint_types])
        self._t0 = int(self.t[0]) if len(self.t) else 0
        self._ts = (self.t - self._t0).astype(float)  # exact below 2**53 ns (104 days)

    def __len__(self) -> int:
        return len(self.t)

    def at(self, t: int) -> np.ndarray:
        """The joints (n,) linearly interpolated at stamp ``t`` (ns); a reading at ``t`` exactly
        is returned unchanged."""
        x = float(t - self._t0)
        return np.array([np.interp(x, self._ts, self.q[:, j]) for j in range(self.q.shape[1])])

    def _limit(self, rule: RestRule) -> np.ndarray:
        speed = np.where(self._prismatic, rule.speed_m_s, rule.speed_rad_s)
        return speed * rule.window_s

    def spread(self, lo: int, hi: int) -> np.ndarray:
        """Per joint, max - min of the readings within [lo, hi] (ns) and of the interpolated
        readings at both ends."""
        j0 = int(np.searchsorted(self.t, lo, side="left"))
        j1 = int(np.searchsorted(self.t, hi, side="right"))
        vals = np.vstack([self.at(lo), self.q[j0:j1], self.at(hi)])
        return np.ptp(vals, axis=0)

    def status(self, t: int, rule: RestRule) -> str:
        """:data:`REST`, :data:`MOVING`, :data:`GAP`, :data:`OUTSIDE` or :data:`EMPTY` for an
        image at stamp ``t`` (ns)."""
        h = int(round(rule.window_s * NS / 2))
        lo, hi = t - h, t + h
        j0 = int(np.searchsorted(self.t, lo, side="left"))
        j1 = int(np.searchsorted(self.t, hi, side="right"))
        if j1 == j0:
            inside = len(self.t) > 0 and self.t[0] <= t <= self.t[-1]
            return EMPTY if inside else OUTSIDE
        i0 = int(np.searchsorted(self.t, lo, side="right")) - 1
        i1 = int(np.searchsorted(self.t, hi, side="left"))
        if i0 < 0 or i1 >= len(self.t):
            return OUTSIDE
        if np.diff(self.t[i0 : i1 + 1]).max(initial=0) > rule.max_gap_s * NS:
            return GAP
        return REST if (self.spread(lo, hi) <= self._limit(rule)).all() else MOVING

    def same_rest(self, ta: int, tb: int, rule: RestRule) -> bool:
        """Whether the arm stayed at rest from stamp ``ta`` to ``tb`` (ns, either order): the
        readings over both windows and the time between spread no more than one window allows."""
        h = int(round(rule.window_s * NS / 2))
        lo, hi = min(ta, tb) - h, max(ta, tb) + h
        return bool((self.spread(lo, hi) <= self._limit(rule)).all())

    def largest_gap(self, t: int) -> tuple[float, float]:
        """The gap (start, end) in s of the joint stamps around stamp ``t`` (ns)."""
        i = int(np.clip(np.searchsorted(self.t, t), 1, max(len(self.t) - 1, 1)))
        return float(self.t[i - 1]) / NS, float(self.t[min(i, len(self.t) - 1)]) / NS


def pair_frames(
    stamps: Mapping[str, Sequence[int]], names: Sequence[str], track: JointTrack, rule: RestRule
) -> list[list[int]]:
    """Frames of the images at rest whose stamps (ns) are ``stamps[camera]``: per frame the
    image index of every camera (``names`` order), the first camera's images in stamp order,
    each other camera's nearest unused image of the same rest."""
    ref = stamps[names[0]]
    used = {n: np.zeros(len(stamps[n]), bool) for n in names[1:]}
    order = {n: np.argsort(stamps[n], kind="stable") for n in names[1:]}
    sorted_t = {n: np.asarray(stamps[n], np.int64)[order[n]] for n in names[1:]}
    frames = []
    for i in np.argsort(ref, kind="stable"):
        t = ref[i]
        frame = [int(i)]
        for n in names[1:]:
            st, k0 = sorted_t[n], int(np.searchsorted(sorted_t[n], t))
            cand = sorted(
                range(max(k0 - 50, 0), min(k0 + 50, len(st))), key=lambda k: abs(st[k] - t)
            )
            pick = next((int(order[n][k]) for k in cand if not used[n][order[n][k]]
                         and track.same_rest(t, int(st[k]), rule)), None)  # fmt: skip
            if pick is None:
                break
            frame.append(pick)
        else:
            for n, k in zip(names[1:], frame[1:]):
                used[n][k] = True
            frames.append(frame)
    return frames


def thin_rests(frames: list[list[int]], stamps: Sequence[int], track: JointTrack,
               rule: RestRule, n: int | None) -> list[list[int]]:  # fmt: skip
    """Of :func:`pair_frames`' ``frames`` (``stamps``: the first camera's), at most ``n`` frames of each rest, evenly spread over it (``n`` = 1: its middle frame,
    the one farthest from the motions before and after); all when ``n`` is None."""
    if n is None or not frames:
        return frames
    groups: list[list[list[int]]] = [[frames[0]]]
    for f in frames[1:]:
        if track.same_rest(stamps[groups[-1][-1][0]], stamps[f[0]], rule):
            groups[-1].append(f)
        else:
            groups.append([f])
    keep = []
    for g in groups:
        if n == 1:
            idx = np.array([(len(g) - 1) // 2])
        else:
            idx = np.unique(np.round(np.linspace(0, len(g) - 1, min(n, len(g)))).astype(int))
        keep += [g[k] for k in idx]
    return keep
