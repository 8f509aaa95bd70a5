"""Faults of ``selfcal emulate --fault KIND --fault-at N [--seed S]``: a person at the robot
rehearses what the acquisition does when the controller fails (docs/hardware.md, "Rehearsing
faults").

``N`` is the acquisition frame (0-based) during which the fault hits; without ``--fault-at`` it is
drawn from ``--seed`` (1 .. 9), and ``--fault random`` draws the kind too. The mapping to ACL
commands follows the acquisition loop: one ``MOVE`` and two ``LISTPV`` per frame.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import InputError
from selfcal.hw.emulator.faults import Fault

__all__ = ["CLI_FAULTS", "acquisition_fault", "choose_fault"]

CLI_FAULTS = ("timeout", "garble", "impact", "disconnect")
"""Kinds ``--fault`` takes (besides ``random``)."""


def acquisition_fault(kind: str, frame: int, *, axis: int = 2) -> Fault:
    """The emulator fault that hits acquisition frame ``frame`` (0-based).

    ``timeout``: the frame's MOVE gets no reply. ``garble``: the frame's joint read-back (LISTPV)
    is garbled on all 3 attempts of the query. ``impact``: the arm hits something 30 % into the
    frame's MOVE (``*** IMPACT PROTECTION axis`` ``axis``). ``disconnect``: the link closes right
    after the frame's MOVE.

    Raises:
        InputError: unknown kind or a negative frame.
    """
    if frame < 0:
        raise InputError(f"--fault-at must be a frame number >= 0, got {frame}")
    if kind == "timeout":
        return Fault("timeout", on="MOVE", skip=frame)
    if kind == "garble":
        return Fault("garble", on="LISTPV", skip=2 * frame, count=3)
    if kind == "impact":
        return Fault("impact", on="MOVE", skip=frame, axis=axis, at_fraction=0.3)
    if kind == "disconnect":
        return Fault("disconnect", on="MOVE", skip=frame, after_s=0.0)
    raise InputError(
        f"unknown --fault {kind!r}; known: {', '.join(CLI_FAULTS)}, random",
        fix="give --fault timeout|garble|impact|disconnect|random",
    )


def choose_fault(kind: str, at: int | None, seed: int) -> tuple[str, int]:
    """The fault kind and frame of the command line: ``random`` and a missing ``--fault-at``
    drawn from ``seed`` (frames 1 .. 9)."""
    rng = np.random.default_rng(seed)
    if kind == "random":
        kind = str(rng.choice(CLI_FAULTS))
    if at is None:
        at = int(rng.integers(1, 10))
    return kind, at
