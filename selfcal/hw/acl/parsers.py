"""Parsers of the ACL replies the adapter reads: ``LISTPV``, ``PRINT MFLAG``, ``SHOW SPEED`` and
``VER``. Units: counts and tenths as the controller prints them; conversion lives in
``selfcal.hw.encoders``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from selfcal.hw.acl.errors import AclControllerError, AclProtocolError
from selfcal.hw.acl.reply import AclReply
from selfcal.hw.acl.text import MAX_INT_DIGITS, quote_bytes

__all__ = [
    "ListPV",
    "AclVersion",
    "parse_listpv",
    "parse_mflag",
    "parse_show_speed",
    "parse_version",
]

_POS_HEADER = re.compile(r"^Position\s+(?P<name>\S+)\s*$", re.I)
_JOINT_LINE = re.compile(r"^\s*\d+\s*:\s*-?\d+(?:\s+\d+\s*:\s*-?\d+)*\s*$")
_JOINT_PAIR = re.compile(r"(\d+)\s*:\s*(-?\d+)")
_CART_LINE = re.compile(r"^\s*[XYZPR]\s*:\s*-?\d+(?:\s+[XYZPR]\s*:\s*-?\d+)*\s*$", re.I)
_CART_PAIR = re.compile(r"([XYZPR])\s*:\s*(-?\d+)", re.I)


def _reply_int(digits: str, reply: AclReply) -> int:
    """An integer the controller printed; more than ``MAX_INT_DIGITS`` digits is a garbled reply."""
    if len(digits.lstrip("+-").lstrip("0")) > MAX_INT_DIGITS:
        raise AclProtocolError(
            f"a number of {len(digits)} digits in the reply to {reply.command!r} (at most "
            f"{MAX_INT_DIGITS} expected): {quote_bytes(reply.raw)}",
            reply.raw,
        )
    return int(digits)


def _raise_reply_errors(reply: AclReply) -> None:
    """Raise for an error that answers the command (``NO POSITION ASSIGNED ...``). Asynchronous
    ``***`` lines interleaved with a query's reply do not invalidate it: they stay in
    ``reply.errors`` (and the link's ``events``) for the caller to act on."""
    for ev in reply.errors:
        if ev.asynchronous:
            continue
        raise AclControllerError(
            f"controller answered {reply.command!r} with '{ev.message}'", event=ev
        )


@dataclass(frozen=True)
class ListPV:
    """A parsed ``LISTPV`` reply.

    Attributes:
        position: the position name from the ``Position ...`` header, if printed.
        counts: encoder counts per axis number (1-based), as printed (may include axes 6-8).
        cartesian: raw Cartesian values: X/Y/Z in 0.1 mm, P/R in 0.1 deg.
    """

    position: str | None
    counts: dict[int, int]
    cartesian: dict[str, int] = field(default_factory=dict)

    def axis_counts(self, n: int) -> np.ndarray:
        """Counts of axes 1..n as an int64 array; raises ``AclProtocolError`` if one is missing."""
        missing = [a for a in range(1, n + 1) if a not in self.counts]
        if missing:
            raise AclProtocolError(
                f"LISTPV reply lists axes {sorted(self.counts)} but axes {missing} are needed"
            )
        return np.array([self.counts[a] for a in range(1, n + 1)], dtype=np.int64)

    @property
    def xyz_mm(self) -> np.ndarray | None:
        if not all(k in self.cartesian for k in "XYZ"):
            return None
        return np.array([self.cartesian[k] for k in "XYZ"], dtype=float) / 10.0

    @property
    def pitch_deg(self) -> float | None:
        return self.cartesian["P"] / 10.0 if "P" in self.cartesian else None

    @property
    def roll_deg(self) -> float | None:
        return self.cartesian["R"] / 10.0 if "R" in self.cartesian else None


def parse_listpv(reply: AclReply) -> ListPV:
    """Parse ``LISTPV POSITION`` / ``LISTPV pos``.

    Raises:
        AclControllerError: the controller answered with an error (e.g. no position assigned).
        AclProtocolError: a line is neither header, joint counts nor Cartesian values, an axis is
            repeated, or the joint line is missing (the message quotes the bytes).
    """
    _raise_reply_errors(reply)
    name = None
    counts: dict[int, int] = {}
    cart: dict[str, int] = {}
    for line in reply.lines:
        hm = _POS_HEADER.match(line)
        if hm:
            name = hm.group("name")
        elif _JOINT_LINE.match(line):
            for a, v in _JOINT_PAIR.findall(line):
                ax = _reply_int(a, reply)
                if ax in counts or ax < 1:
                    raise AclProtocolError(
                        f"LISTPV reply repeats or misnumbers axis {ax}: {quote_bytes(reply.raw)}",
                        reply.raw,
                    )
                counts[ax] = _reply_int(v, reply)
        elif _CART_LINE.match(line):
            for k, v in _CART_PAIR.findall(line):
                k = k.upper()
                if k in cart:
                    raise AclProtocolError(
                        f"LISTPV reply repeats {k}: {quote_bytes(reply.raw)}", reply.raw
                    )
                cart[k] = _reply_int(v, reply)
        else:
            raise AclProtocolError(
                f"unexpected line {line!r} in the reply to {reply.command!r}: "
                f"{quote_bytes(reply.raw)}",
                reply.raw,
            )
    if not counts:
        raise AclProtocolError(
            f"no joint counts in the reply to {reply.command!r}: {quote_bytes(reply.raw)}",
            reply.raw,
        )
    axes = sorted(counts)
    if axes != list(range(1, len(axes) + 1)):
        raise AclProtocolError(
            f"LISTPV axes {axes} are not consecutive from 1: {quote_bytes(reply.raw)}", reply.raw
        )
    return ListPV(name, counts, cart)


def parse_mflag(reply: AclReply) -> int:
    """Parse ``PRINT MFLAG``: the bit mask of axes in motion (0 when still)."""
    _raise_reply_errors(reply)
    if len(reply.lines) != 1 or not re.fullmatch(r"\d+", reply.lines[0].strip()):
        raise AclProtocolError(
            f"expected one non-negative integer in the reply to {reply.command!r}, got "
            f"{quote_bytes(reply.raw)}",
            reply.raw,
        )
    return _reply_int(reply.lines[0].strip(), reply)


def parse_show_speed(reply: AclReply) -> dict[str, int]:
    """Parse ``SHOW SPEED`` (``GROUP A SPEED IS: 40`` ... ``O.K.``) into ``{"A": 40, ...}``."""
    _raise_reply_errors(reply)
    out: dict[str, int] = {}
    for line in reply.lines:
        m = re.fullmatch(r"GROUP\s+(\w)\s+SPEED\s+IS\s*:?\s*(\d+)", line.strip(), re.I)
        if m:
            out[m.group(1).upper()] = _reply_int(m.group(2), reply)
        elif line.strip().upper().rstrip(".") not in ("O.K", "OK"):
            raise AclProtocolError(
                f"unexpected line {line!r} in the reply to SHOW SPEED: {quote_bytes(reply.raw)}",
                reply.raw,
            )
    if not out:
        raise AclProtocolError(f"no speed in the reply to SHOW SPEED: {quote_bytes(reply.raw)}")
    return out


@dataclass(frozen=True)
class AclVersion:
    """The ``VER`` banner: all lines plus the version and date when printed."""

    lines: tuple[str, ...]
    version: str | None
    date: str | None


def parse_version(reply: AclReply) -> AclVersion:
    """Parse the ``VER`` banner (``ESHED ROBOTEC`` / ``VERSION: 1.42`` / ``DATE : 21/07/91``)."""
    _raise_reply_errors(reply)
    version = date = None
    for line in reply.lines:
        m = re.match(r"^\s*VER(?:SION)?\s*:?\s*(\S.*)$", line, re.I)
        if m and version is None:
            version = m.group(1).strip()
        m = re.match(r"^\s*DATE\s*:?\s*(\S.*)$", line, re.I)
        if m and date is None:
            date = m.group(1).strip()
    if not reply.lines:
        raise AclProtocolError(f"empty reply to VER: {quote_bytes(reply.raw)}", reply.raw)
    return AclVersion(tuple(reply.lines), version, date)
