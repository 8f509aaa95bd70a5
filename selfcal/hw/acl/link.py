"""``AclLink``: the ACL dialogue over a serial line.

``serial.serial_for_url`` opens the port, so one string selects a device path,
``socket://host:port``, ``loop://`` or a pseudo-terminal. The link sends commands and reads their
replies (``selfcal.hw.acl.reply``), retries queries only (a bounded number of times), resynchronises after
a bad reply, and sends the abort sequence (Ctrl-A, then ``CLRBUF``). ``port_hint`` says what to
check when a port cannot be opened or does not answer.
"""

from __future__ import annotations

import os
import re
import time
from collections import deque
from collections.abc import Callable
from typing import Any, TypeVar

import serial

from selfcal.errors import UsageError
from selfcal.hw.acl.errors import (
    AclConnectionError,
    AclErrorEvent,
    AclProtocolError,
    AclTimeoutError,
    extract_error_events,
    split_error,
)
from selfcal.hw.acl.reply import AclReply, ReplyAssembler
from selfcal.hw.acl.text import CTRL_A, IGNORED_BYTES, LEADING_PROMPT, LINE_SPLIT, quote_bytes

__all__ = ["AclLink", "open_serial", "port_hint"]

try:  # tcdrain/tcflush on a vanished pty raise termios.error, which is not an OSError
    import termios

    _TERMIOS_ERRORS: tuple[type[Exception], ...] = (termios.error,)
except ImportError:  # pragma: no cover - not POSIX
    _TERMIOS_ERRORS = ()

_LINK_ERRORS = (serial.SerialException, OSError, *_TERMIOS_ERRORS)
"""Exceptions from pyserial ports that mean the link itself failed."""

T = TypeVar("T")


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
        text = bytes(b for b in buf if b not in IGNORED_BYTES).decode("latin-1")
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
                try:
                    asm.feed(data)
                except AclProtocolError as exc:
                    self._dirty = True
                    self.events.extend(exc.events)
                    raise
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
            raise UsageError(f"an ACL command is one line, got {cmd!r}")
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
            text = bytes(b for b in buf if b not in IGNORED_BYTES).decode("latin-1")
            parts = LINE_SPLIT.split(text)
            for line in parts[:-1][done:]:
                done += 1
                before, ev = split_error(line)
                if ev is not None:
                    self.events.append(ev)
                    return lines, None
                line = LEADING_PROMPT.sub("", before).strip()
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
        """Close the port, also a ``socket://`` one whose peer is gone: pyserial's close skips
        the socket's own close when its shutdown fails (the peer already closed), leaving the
        socket open until garbage collection (a ResourceWarning)."""
        sock = getattr(self.port, "_socket", None)
        try:
            self.port.close()
        except _LINK_ERRORS:
            pass
        finally:
            if sock is not None:
                sock.close()
