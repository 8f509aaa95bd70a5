"""Fault injection for the ACL controller emulator: the ``Fault`` description, which command it
fires on, and what it does to a reply's bytes.

Kinds (``FAULT_KINDS``): ``timeout`` (no reply at all; the command still takes effect unless
``execute=False``), ``garble`` (bit errors: every third reply byte gets its top bit flipped),
``drop`` (every second reply byte is lost), ``impact`` (during the triggering MOVE, at
``at_fraction`` of it: the arm stops, ``*** IMPACT PROTECTION axis n`` is printed asynchronously,
control goes off), ``disconnect`` (``after_s`` after the triggering command every connection is
closed; the pty disappears), ``home_failure`` (``*** HOME FAILURE AXIS n`` instead of homing).
The controller (``selfcal.hw.emulator.controller``) acts them out.
"""

from __future__ import annotations

from dataclasses import dataclass

from selfcal.errors import InputError

__all__ = ["FAULT_KINDS", "Fault", "take_fault", "garble", "drop"]

FAULT_KINDS = ("timeout", "garble", "drop", "impact", "disconnect", "home_failure")


@dataclass
class Fault:
    """One injected fault (see the module docstring for the kinds).

    Attributes:
        kind: one of ``FAULT_KINDS``.
        on: command prefix that triggers it (case-insensitive, e.g. ``"MOVE"``, ``"PRINT MFLAG"``,
            ``"LISTPV"``); ``None``: the next command.
        count: how many times it fires; ``-1``: every time.
        axis: axis named by ``impact`` / ``home_failure``.
        at_fraction: ``impact``: fraction of the motion after which the arm hits.
        after_s: ``disconnect``: delay after the triggering command.
        execute: ``timeout``: whether the unanswered command still takes effect.
        skip: let this many matching commands pass before the fault fires (e.g. ``on="MOVE",
            skip=5``: the sixth MOVE).
    """

    kind: str
    on: str | None = None
    count: int = 1
    axis: int = 2
    at_fraction: float = 0.4
    after_s: float = 0.05
    execute: bool = True
    skip: int = 0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise InputError(f"unknown fault kind {self.kind!r}; known: {', '.join(FAULT_KINDS)}")
        if self.count == 0 or self.count < -1:
            raise InputError(f"fault count must be positive or -1 (always), got {self.count}")
        if self.skip < 0:
            raise InputError(f"fault skip must be >= 0, got {self.skip}")
        if not 0.0 <= self.at_fraction <= 1.0:
            raise InputError(f"at_fraction must be in [0, 1], got {self.at_fraction}")

    def matches(self, command: str) -> bool:
        return self.on is None or command.startswith(" ".join(self.on.upper().split()))


def take_fault(faults: list[Fault], command: str) -> Fault | None:
    """The first fault in ``faults`` that fires on ``command`` (normalised, upper case), or
    ``None``; counts its ``skip`` down first, then its ``count``, and removes a spent fault from
    ``faults``."""
    for f in faults:
        if f.matches(command):
            if f.skip > 0:
                f.skip -= 1
                continue
            if f.count > 0:
                f.count -= 1
                if f.count == 0:
                    faults.remove(f)
            return f
    return None


def garble(text: str) -> str:
    """Bit errors: every third byte (from the second) gets its top bit flipped."""
    b = bytearray(text.encode("latin-1"))
    for i in range(1, len(b), 3):
        b[i] ^= 0x80
    return b.decode("latin-1")


def drop(text: str) -> str:
    """Lost bytes: every second byte is dropped."""
    return text[::2]
