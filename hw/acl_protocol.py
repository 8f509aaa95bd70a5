"""ACL (the SCORBOT controllers' Advanced Control Language) over a serial line.

Three layers, each usable on its own:

- ``ReplyAssembler``: a pure, incremental reader. Fed the bytes that follow a command, it decides
  when the reply is complete (the ``>`` prompt at the start of a line, or after the last value on
  the same line) without ending at ``>`` characters inside replies (``1 -> 16: 0 1``, per-axis
  questions ``1 -- [100] >``, ``(YES/NO)>``), strips the echoed command (echo on or off), accepts
  ``\\r`` or ``\\r\\n`` line ends, drops XON/XOFF (0x11/0x13) and NUL bytes, and pulls out
  asynchronous ``***`` error lines wherever they appear.
- ``parse_*``: parsers for ``LISTPV``, ``PRINT MFLAG``, ``SHOW SPEED``, ``VER`` and error lines.
- ``AclLink``: the serial dialogue (``serial.serial_for_url``, so one string selects a device path,
  ``socket://host:port``, ``loop://`` or a pseudo-terminal): commands, bounded retries for queries
  only, resynchronisation after a bad reply, and the abort sequence (Ctrl-A, then ``CLRBUF``).

Units: counts and tenths as the controller prints them; conversion lives in ``hw.encoders``.
"""

from __future__ import annotations

import os
import re
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np
import serial

from calib.robot import RobotError

__all__ = [
    "CTRL_A",
    "XON",
    "XOFF",
    "AclProtocolError",
    "AclTimeoutError",
    "AclConnectionError",
    "AclControllerError",
    "AclLatchedError",
    "AclErrorEvent",
    "AclReply",
    "ReplyAssembler",
    "ListPV",
    "AclVersion",
    "parse_error_line",
    "extract_error_events",
    "parse_listpv",
    "parse_mflag",
    "parse_show_speed",
    "parse_version",
    "AclLink",
    "open_serial",
    "quote_bytes",
]

try:  # tcdrain/tcflush on a vanished pty raise termios.error, which is not an OSError
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover - not POSIX
    _TermiosError = OSError

_LINK_ERRORS = (serial.SerialException, OSError, _TermiosError)
"""Exceptions from pyserial ports that mean the link itself failed."""

CTRL_A = 0x01
XON = 0x11
XOFF = 0x13
_IGNORED_BYTES = bytes([0x00, XON, XOFF])
_ALLOWED_CONTROL = {0x09, 0x0A, 0x0D}

T = TypeVar("T")


def quote_bytes(raw: bytes, limit: int = 400) -> str:
    """``repr`` of received bytes for error messages, shortened in the middle if long."""
    raw = bytes(raw)
    if len(raw) <= limit:
        return repr(raw)
    half = limit // 2
    return f"{raw[:half]!r} ... ({len(raw) - 2 * half} bytes) ... {raw[-half:]!r}"


# --------------------------------------------------------------------------------------------
# errors
# --------------------------------------------------------------------------------------------


class AclProtocolError(RobotError):
    """The controller's reply was garbled, incomplete or unexpected; ``raw`` holds the bytes."""

    def __init__(self, message: str, raw: bytes = b"", events: tuple = ()):
        super().__init__(message)
        self.raw = bytes(raw)
        self.events = tuple(events)


class AclTimeoutError(AclProtocolError):
    """No complete reply (no prompt) within the timeout; ``raw`` holds what did arrive."""


class AclConnectionError(AclProtocolError):
    """The serial link itself failed (port closed, device unplugged, socket disconnected)."""


@dataclass(frozen=True)
class AclErrorEvent:
    """One error reported by the controller.

    Attributes:
        kind: ``impact_protection``, ``out_of_range``, ``thermic_overload``, ``trajectory_error``,
            ``upper_limit``, ``lower_limit``, ``home_failure``, ``no_position``,
            ``bad_point_coordinate``, ``bad_cartesian_point``, ``axis_disabled`` or
            ``controller_error`` (any other ``***`` line).
        message: the controller's text, stripped.
        axis: the axis number the message names (1-based), if any.
        position: the position name (``NO POSITION ASSIGNED TO POINT pos``), if any.
    """

    kind: str
    message: str
    axis: int | None = None
    position: str | None = None

    @property
    def asynchronous(self) -> bool:
        """``***`` errors are printed asynchronously (e.g. during a motion)."""
        return self.message.startswith("***")

    @property
    def latching(self) -> bool:
        """Errors after which the adapter refuses motion until control is re-enabled."""
        return self.asynchronous or self.kind == "axis_disabled"

    def __str__(self) -> str:
        return self.message


class AclControllerError(RobotError):
    """The controller reported an error (``event``); the message names axis and controller text."""

    def __init__(self, message: str, event: AclErrorEvent | None = None):
        super().__init__(message)
        self.event = event

    @property
    def axis(self) -> int | None:
        return self.event.axis if self.event else None


class AclLatchedError(AclControllerError):
    """Motion refused: an earlier controller error is latched until ``reset_errors()``."""


_AXIS_ERRORS = {
    "IMPACT PROTECTION": "impact_protection",
    "OUT OF RANGE": "out_of_range",
    "THERMIC OVERLOAD": "thermic_overload",
    "UPPER LIMIT": "upper_limit",
    "LOWER LIMIT": "lower_limit",
    "HOME FAILURE": "home_failure",
}
_STAR_RE = re.compile(r"\*\*\*\s*(?P<msg>.*)$")
_AXIS_ERR_RE = re.compile(
    r"^(?P<what>" + "|".join(_AXIS_ERRORS) + r")\s*(?:ON\s+)?AXIS\s*(?P<axis>\d+)", re.IGNORECASE
)
_PLAIN_ERRORS = (
    (re.compile(r"^NO\s+POSITION\s+ASSIGNED\s+TO\s+POINT\s*(?P<pos>\S*)", re.I), "no_position"),
    (re.compile(r"^BAD\s+POINT\s+COORDINATE", re.I), "bad_point_coordinate"),
    (re.compile(r"^BAD\s+CARTESIAN\s+POINT", re.I), "bad_cartesian_point"),
    (re.compile(r"^AXIS\s+DISABLED(?:\s+(?P<axis>\d+))?", re.I), "axis_disabled"),
)


def parse_error_line(line: str) -> AclErrorEvent | None:
    """Recognise one controller error line (``*** ...`` or a known plain message), else ``None``."""
    text = line.strip().lstrip(">").strip()
    m = _STAR_RE.match(text)
    if m:
        msg = m.group("msg").strip()
        message = f"*** {msg}"
        am = _AXIS_ERR_RE.match(msg)
        if am:
            kind = _AXIS_ERRORS[re.sub(r"\s+", " ", am.group("what").upper())]
            return AclErrorEvent(kind, message, axis=int(am.group("axis")))
        if re.match(r"^TRAJECTORY\s+ERROR", msg, re.I):
            return AclErrorEvent("trajectory_error", message)
        for rx, kind in _PLAIN_ERRORS:
            pm = rx.match(msg)
            if pm:
                gd = pm.groupdict()
                axis = int(gd["axis"]) if gd.get("axis") else None
                return AclErrorEvent(kind, message, axis=axis, position=gd.get("pos") or None)
        return AclErrorEvent("controller_error", message)
    for rx, kind in _PLAIN_ERRORS:
        pm = rx.match(text)
        if pm:
            gd = pm.groupdict()
            axis = int(gd["axis"]) if gd.get("axis") else None
            return AclErrorEvent(kind, text, axis=axis, position=gd.get("pos") or None)
    return None


def _split_error(line: str) -> tuple[str, AclErrorEvent | None]:
    """Split a line into (text before an error, error event). ``***`` may start mid-line."""
    idx = line.find("***")
    if idx >= 0:
        return line[:idx], parse_error_line(line[idx:])
    ev = parse_error_line(line)
    if ev is not None:
        return "", ev
    return line, None


def extract_error_events(text: str) -> list[AclErrorEvent]:
    """All error events in a block of text (any line ends)."""
    out = []
    for line in _LINE_SPLIT.split(text):
        _, ev = _split_error(line)
        if ev is not None:
            out.append(ev)
    return out


# --------------------------------------------------------------------------------------------
# the reply reader
# --------------------------------------------------------------------------------------------

_LINE_SPLIT = re.compile(r"\r\n|\r|\n")
_PROMPT_ALONE = re.compile(r"^\s*>[\s_]*$")
_PROMPT_SAME_LINE = re.compile(r"^(?P<body>.*?[^\s\-=<>])\s*>[\s_]*$")
_QUESTION = re.compile(
    r"(?:^\s*\d+\s*--\s*\[[^\]]*\]\s*>[\s_]*$)|(?:\(\s*YES\s*/\s*NO\s*\)\s*>[\s_]*$)", re.I
)
_LEADING_PROMPT = re.compile(r"^\s*>+\s*")


def _norm_cmd(s: str) -> str:
    return " ".join(s.upper().split())


@dataclass(frozen=True)
class AclReply:
    """A complete reply to one command.

    Attributes:
        command: the command sent (without CR).
        lines: reply lines without echo, prompt, blank lines and error lines.
        errors: controller error events found anywhere in the reply.
        echoed: whether the command's echo was seen (and removed).
        question: the pending question (``1 -- [100] >``, ``... (YES/NO)>``) if the controller is
            waiting for input instead of showing its prompt, else ``None``.
        prompt_same_line: the prompt came after the last value on the same line.
        raw: every byte received for this reply.
    """

    command: str
    lines: tuple[str, ...]
    errors: tuple[AclErrorEvent, ...] = ()
    echoed: bool = False
    question: str | None = None
    prompt_same_line: bool = False
    raw: bytes = b""

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


class ReplyAssembler:
    """Incremental reader of one ACL reply. Pure: no I/O, no clock.

    ``feed(bytes)`` then look at ``status``: ``"incomplete"``, ``"complete"`` (prompt at the start of
    a line, or a question waiting for input) or ``"maybe"`` (a ``>`` after the last value on a
    content line, or a ``>`` that is the first thing received: complete if nothing more arrives
    within a short settle time).

    Args:
        command: the command whose reply this is (used to recognise and strip its echo); ``None``
            for unsolicited text.
        expect_echo: if true, a prompt only ends the reply after the echo has been seen (protects
            against a stale prompt left over from an earlier exchange).
    """

    INCOMPLETE, COMPLETE, MAYBE = "incomplete", "complete", "maybe"

    def __init__(self, command: str | None, expect_echo: bool = False):
        self.command = command
        self.expect_echo = bool(expect_echo) and bool(command)
        self.raw = bytearray()
        self._status = self.INCOMPLETE
        self._analysis: dict[str, Any] = {}

    def feed(self, data: bytes) -> str:
        """Add received bytes; returns the new status."""
        if data:
            self.raw += data
            self._analyse()
        return self._status

    @property
    def status(self) -> str:
        return self._status

    @property
    def text(self) -> str:
        """Received text with XON/XOFF/NUL removed (latin-1, so every byte maps to one char)."""
        return bytes(b for b in self.raw if b not in _IGNORED_BYTES).decode("latin-1")

    def garbled_bytes(self) -> bytes:
        """Bytes that cannot occur in an ACL reply (non-ASCII or stray control characters)."""
        return bytes(
            b
            for b in self.raw
            if b not in _IGNORED_BYTES and (b >= 0x7F or (b < 0x20 and b not in _ALLOWED_CONTROL))
        )

    def _analyse(self) -> None:
        text = self.text
        parts = _LINE_SPLIT.split(text)
        complete_lines, tail = parts[:-1], parts[-1]
        want = _norm_cmd(self.command) if self.command else None
        lines: list[str] = []
        errors: list[AclErrorEvent] = []
        echoed = False
        content_seen = False
        for raw_line in complete_lines:
            before, ev = _split_error(raw_line)
            if ev is not None:
                errors.append(ev)
            line = _LEADING_PROMPT.sub("", before).strip()
            if not line:
                continue
            if want is not None and not echoed and not content_seen and _norm_cmd(line) == want:
                echoed = True
                continue
            content_seen = True
            lines.append(line)
        status = self.INCOMPLETE
        question = None
        same_line = False
        # an error line whose line end has not arrived yet: wait for the rest of it
        tail_has_error = "***" in tail and _split_error(tail)[1] is not None
        if not tail_has_error:
            echo_ok = echoed or not self.expect_echo
            if _QUESTION.search(tail):
                status, question = self.COMPLETE, tail.strip()
            elif _PROMPT_ALONE.match(tail):
                if echo_ok:
                    # a prompt that is the very first thing received may be a stale one (the
                    # echo or reply can still follow): confirm it by a quiet period
                    nothing_before = not echoed and not lines and not errors
                    status = self.MAYBE if nothing_before else self.COMPLETE
            else:
                m = _PROMPT_SAME_LINE.match(tail)
                if m and echo_ok:
                    status, same_line = self.MAYBE, True
                    body = _LEADING_PROMPT.sub("", m.group("body")).strip()
                    if body:
                        lines.append(body)
        self._status = status
        self._analysis = dict(
            lines=tuple(lines),
            errors=tuple(errors),
            echoed=echoed,
            question=question,
            same_line=same_line,
        )

    def events(self) -> tuple[AclErrorEvent, ...]:
        """Error events seen so far (complete lines only)."""
        return tuple(self._analysis.get("errors", ()))

    def result(self) -> AclReply:
        """The reply (call once ``status`` is complete, or accepted ``maybe``).

        Raises:
            AclProtocolError: the bytes contain characters an ACL reply cannot contain.
        """
        a = self._analysis or {}
        bad = self.garbled_bytes()
        if bad:
            raise AclProtocolError(
                f"garbled reply to {self.command!r}: {len(bad)} invalid byte(s) "
                f"{quote_bytes(bad, 40)} in {quote_bytes(bytes(self.raw))}",
                bytes(self.raw),
                a.get("errors", ()),
            )
        return AclReply(
            command=self.command or "",
            lines=a.get("lines", ()),
            errors=a.get("errors", ()),
            echoed=a.get("echoed", False),
            question=a.get("question"),
            prompt_same_line=a.get("same_line", False),
            raw=bytes(self.raw),
        )


# --------------------------------------------------------------------------------------------
# parsers
# --------------------------------------------------------------------------------------------

_POS_HEADER = re.compile(r"^Position\s+(?P<name>\S+)\s*$", re.I)
_JOINT_LINE = re.compile(r"^\s*\d+\s*:\s*-?\d+(?:\s+\d+\s*:\s*-?\d+)*\s*$")
_JOINT_PAIR = re.compile(r"(\d+)\s*:\s*(-?\d+)")
_CART_LINE = re.compile(r"^\s*[XYZPR]\s*:\s*-?\d+(?:\s+[XYZPR]\s*:\s*-?\d+)*\s*$", re.I)
_CART_PAIR = re.compile(r"([XYZPR])\s*:\s*(-?\d+)", re.I)


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
                ax = int(a)
                if ax in counts or ax < 1:
                    raise AclProtocolError(
                        f"LISTPV reply repeats or misnumbers axis {ax}: {quote_bytes(reply.raw)}",
                        reply.raw,
                    )
                counts[ax] = int(v)
        elif _CART_LINE.match(line):
            for k, v in _CART_PAIR.findall(line):
                k = k.upper()
                if k in cart:
                    raise AclProtocolError(
                        f"LISTPV reply repeats {k}: {quote_bytes(reply.raw)}", reply.raw
                    )
                cart[k] = int(v)
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
    return int(reply.lines[0])


def parse_show_speed(reply: AclReply) -> dict[str, int]:
    """Parse ``SHOW SPEED`` (``GROUP A SPEED IS: 40`` ... ``O.K.``) into ``{"A": 40, ...}``."""
    _raise_reply_errors(reply)
    out: dict[str, int] = {}
    for line in reply.lines:
        m = re.fullmatch(r"GROUP\s+(\w)\s+SPEED\s+IS\s*:?\s*(\d+)", line.strip(), re.I)
        if m:
            out[m.group(1).upper()] = int(m.group(2))
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


# --------------------------------------------------------------------------------------------
# the link
# --------------------------------------------------------------------------------------------


def open_serial(
    url: str,
    *,
    baudrate: int = 9600,
    bytesize: int = 8,
    parity: str = "N",
    stopbits: float = 1,
    xonxoff: bool = True,
    read_timeout_s: float = 0.02,
    write_timeout_s: float | None = 2.0,
) -> serial.SerialBase:
    """Open ``url`` with ``serial.serial_for_url`` (device path, ``socket://``, ``loop://``, pty).

    ``read_timeout_s`` is the port's own (short) read timeout; reply deadlines live in ``AclLink``.

    Raises:
        AclConnectionError: the port cannot be opened (the message names it).
    """
    try:
        return serial.serial_for_url(
            url,
            baudrate=baudrate,
            bytesize=bytesize,
            parity=parity,
            stopbits=stopbits,
            xonxoff=xonxoff,
            timeout=read_timeout_s,
            write_timeout=write_timeout_s,
        )
    except (*_LINK_ERRORS, ValueError) as exc:
        raise AclConnectionError(
            f"cannot open ACL port {url!r}: {exc} (check [robot.hardware] port: {port_hint(url)})"
        ) from exc


def port_hint(url: str) -> str:
    """What to check when the ACL port ``url`` cannot be opened or does not answer."""
    u = str(url)
    if u.startswith("socket://"):
        return (
            f"is the ACL bridge or `selfcal emulate` running and listening at {u[9:]}? "
            "(the emulator prints its tcp: address when it starts)"
        )
    if "://" in u:
        return "a pyserial URL (socket://host:port, loop://, rfc2217://...) with a reachable end"
    real = os.path.realpath(u)
    if real.startswith("/dev/pts/") or "pts" in u:
        return (
            "an emulator's pseudo-terminal exists only while `selfcal emulate` runs and gets a new "
            "path on every start: copy the pty: path it prints (or give it --pty-link for a "
            "stable name)"
        )
    return (
        "is the USB-RS-232 adapter plugged in (ls /dev/ttyUSB* /dev/serial/by-id/), may you open "
        "it (group dialout), and is the controller on and in DIRECT mode at the configured baud "
        "rate?"
    )


class AclLink:
    """The ACL dialogue over an open pyserial port.

    Args:
        port: an open ``serial.SerialBase`` (its own timeout should be short, e.g. 0.02 s).
        echo: ``True`` if the controller echoes commands (a prompt before the echo is then stale
            and ignored), ``False`` if not, ``None`` to accept both (default).
        query_timeout_s: deadline for an ordinary reply.
        settle_s: quiet time that confirms a prompt printed after a value on the same line.
        retries: extra attempts for queries (never for motion commands).

    Every byte written is appended to ``tx_log`` (before it is written, so a failed write is still
    recorded); every controller error seen is appended to ``events`` until ``pop_events()``.
    """

    def __init__(
        self,
        port: serial.SerialBase,
        *,
        echo: bool | None = None,
        query_timeout_s: float = 2.0,
        settle_s: float = 0.03,
        retries: int = 2,
        log_size: int = 1000,
    ):
        self.port = port
        self.echo = echo
        self.query_timeout_s = float(query_timeout_s)
        self.settle_s = float(settle_s)
        self.retries = int(retries)
        self.tx_log: deque[bytes] = deque(maxlen=log_size)
        self.rx_log: deque[bytes] = deque(maxlen=log_size)
        self.events: list[AclErrorEvent] = []
        self._dirty = False

    @classmethod
    def open(
        cls,
        url: str,
        *,
        baudrate: int = 9600,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        xonxoff: bool = True,
        read_timeout_s: float = 0.02,
        **kwargs: Any,
    ) -> AclLink:
        """Open ``url`` (see ``open_serial``) and wrap it."""
        port = open_serial(
            url,
            baudrate=baudrate,
            bytesize=bytesize,
            parity=parity,
            stopbits=stopbits,
            xonxoff=xonxoff,
            read_timeout_s=read_timeout_s,
        )
        return cls(port, **kwargs)

    # -- low level -----------------------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        return bool(getattr(self.port, "is_open", False))

    def _write(self, data: bytes) -> None:
        self.tx_log.append(bytes(data))
        try:
            self.port.write(data)
            self.port.flush()
        except _LINK_ERRORS as exc:
            self._dirty = True
            raise AclConnectionError(f"serial link lost while writing {data!r}: {exc}") from exc

    def _read_some(self) -> bytes:
        try:
            data = self.port.read(1)
            if data:
                n = self.port.in_waiting
                if n:
                    data += self.port.read(n)
        except _LINK_ERRORS as exc:
            self._dirty = True
            raise AclConnectionError(f"serial link lost while reading: {exc}") from exc
        if data:
            self.rx_log.append(bytes(data))
        return bytes(data)

    def drain(self, quiet_s: float = 0.0, max_s: float = 0.5) -> list[AclErrorEvent]:
        """Read whatever is pending (until ``quiet_s`` without bytes, at most ``max_s``).

        Error lines in it are appended to ``events`` and returned.
        """
        buf = bytearray()
        t_end = time.monotonic() + max_s
        last = time.monotonic()
        while True:
            try:
                n = self.port.in_waiting
            except _LINK_ERRORS as exc:
                raise AclConnectionError(f"serial link lost: {exc}") from exc
            if n:
                buf += self._read_some()
                last = time.monotonic()
            elif time.monotonic() - last >= quiet_s or time.monotonic() > t_end:
                break
            else:
                time.sleep(min(0.005, quiet_s))
            if time.monotonic() > t_end:
                break
        if not buf:
            return []
        text = bytes(b for b in buf if b not in _IGNORED_BYTES).decode("latin-1")
        evs = extract_error_events(text)
        self.events.extend(evs)
        return evs

    def pop_events(self) -> list[AclErrorEvent]:
        """Controller errors seen since the last call (in order)."""
        evs, self.events = self.events, []
        return evs

    def read_reply(
        self, command: str | None, timeout_s: float | None = None, expect_echo: bool | None = None
    ) -> AclReply:
        """Read one reply (the command has been written already).

        Raises:
            AclTimeoutError: no prompt within ``timeout_s`` (quotes the bytes received).
            AclProtocolError: garbled bytes.
            AclConnectionError: the link failed.
        """
        timeout_s = self.query_timeout_s if timeout_s is None else float(timeout_s)
        if expect_echo is None:
            expect_echo = bool(self.echo)
        asm = ReplyAssembler(command, expect_echo=expect_echo)
        deadline = time.monotonic() + timeout_s
        settle_until = None
        while True:
            try:
                data = self._read_some()
            except AclConnectionError as exc:
                self.events.extend(asm.events())
                exc.raw = bytes(asm.raw)
                raise
            now = time.monotonic()
            if data:
                asm.feed(data)
                settle_until = None
            st = asm.status
            if st == ReplyAssembler.COMPLETE:
                break
            if st == ReplyAssembler.MAYBE:
                if settle_until is None:
                    settle_until = now + self.settle_s
                elif now >= settle_until:
                    break
            if now > deadline:
                self._dirty = True
                evs = asm.events()
                self.events.extend(evs)
                raise AclTimeoutError(
                    f"no prompt from the controller within {timeout_s:g} s after {command!r}; "
                    f"received {quote_bytes(bytes(asm.raw))}",
                    bytes(asm.raw),
                    evs,
                )
        try:
            reply = asm.result()
        except AclProtocolError as exc:
            self._dirty = True
            self.events.extend(exc.events)
            raise
        self.events.extend(reply.errors)
        return reply

    # -- dialogue ------------------------------------------------------------------------------

    def command(self, cmd: str, *, timeout_s: float | None = None) -> AclReply:
        """Send one command (CR appended) and read its reply. Never retried.

        Pending input is drained first (errors in it go to ``events``); after an earlier bad
        exchange the link first resynchronises on a fresh prompt.
        """
        if "\r" in cmd or "\n" in cmd:
            raise ValueError(f"an ACL command is one line, got {cmd!r}")
        if self._dirty:
            self.resync()
        self.drain()
        self._write(cmd.encode("ascii") + b"\r")
        return self.read_reply(cmd, timeout_s)

    def query(
        self,
        cmd: str,
        parse: Callable[[AclReply], T],
        *,
        timeout_s: float | None = None,
        retries: int | None = None,
    ) -> T:
        """Send a side-effect-free query and parse its reply, retrying bad replies.

        Timeouts and garbled/unparseable replies (``AclProtocolError``) are retried up to
        ``retries`` times after a resync; link failures and controller errors are not.
        """
        retries = self.retries if retries is None else int(retries)
        last: AclProtocolError | None = None
        for _ in range(retries + 1):
            try:
                return parse(self.command(cmd, timeout_s=timeout_s))
            except AclConnectionError:
                raise
            except AclProtocolError as exc:
                last = exc
                self._dirty = True
        assert last is not None
        cls = type(last)
        raise cls(f"{last} (after {retries + 1} attempts)", last.raw, last.events) from last

    def resync(self, timeout_s: float = 0.5) -> bool:
        """Drain, send a bare CR and wait for a fresh prompt; returns whether one came."""
        self.drain(quiet_s=0.02)
        try:
            self._write(b"\r")
            self.read_reply("", timeout_s, expect_echo=False)
            ok = True
        except AclConnectionError:
            raise
        except AclProtocolError:
            ok = False
        self.drain(quiet_s=0.02)
        self._dirty = not ok
        return ok

    def read_lines_until(
        self, pattern: re.Pattern[str] | str, timeout_s: float
    ) -> tuple[list[str], re.Match[str] | None]:
        """Read complete lines until one matches ``pattern`` or an error line arrives.

        Returns (lines read, the match or ``None`` if an error line ended the wait).

        Raises:
            AclTimeoutError: neither within ``timeout_s``.
        """
        rx = re.compile(pattern) if isinstance(pattern, str) else pattern
        buf = bytearray()
        deadline = time.monotonic() + timeout_s
        done = 0
        lines: list[str] = []
        while True:
            buf += self._read_some()
            text = bytes(b for b in buf if b not in _IGNORED_BYTES).decode("latin-1")
            parts = _LINE_SPLIT.split(text)
            for line in parts[:-1][done:]:
                done += 1
                before, ev = _split_error(line)
                if ev is not None:
                    self.events.append(ev)
                    return lines, None
                line = _LEADING_PROMPT.sub("", before).strip()
                if line:
                    lines.append(line)
                    m = rx.search(line)
                    if m:
                        return lines, m
            if time.monotonic() > deadline:
                self._dirty = True
                raise AclTimeoutError(
                    f"no line matching {rx.pattern!r} within {timeout_s:g} s; received "
                    f"{quote_bytes(bytes(buf))}",
                    bytes(buf),
                )

    def abort(self, timeout_s: float = 0.5) -> list[str]:
        """The abort sequence: Ctrl-A (0x01), then ``CLRBUF``; nothing is sent before them.

        Best effort: each write is attempted even if the previous failed. Returns problems met
        (empty if both were delivered and the controller answered).
        """
        problems: list[str] = []
        for data in (bytes([CTRL_A]), b"CLRBUF\r"):
            try:
                self._write(data)
            except AclConnectionError as exc:
                problems.append(str(exc))
        if not problems:
            try:
                self.read_reply("CLRBUF", timeout_s, expect_echo=False)
            except AclConnectionError as exc:
                problems.append(str(exc))
            except AclProtocolError as exc:
                problems.append(f"no clean prompt after CLRBUF ({exc})")
            try:
                self.drain(quiet_s=0.03)
            except AclConnectionError as exc:
                problems.append(str(exc))
        self._dirty = True
        return problems

    def close(self) -> None:
        try:
            self.port.close()
        except _LINK_ERRORS:
            pass
