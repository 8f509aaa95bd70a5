"""The ACL reply reader: ``ReplyAssembler``, pure and incremental, and the ``AclReply`` it yields.

Fed the bytes that follow a command, the assembler decides when the reply is complete (the ``>``
prompt at the start of a line, or after the last value on the same line) without ending at ``>``
characters inside replies (``1 -> 16: 0 1``, per-axis questions ``1 -- [100] >``, ``(YES/NO)>``),
strips the echoed command (echo on or off), accepts ``\\r`` or ``\\r\\n`` line ends, drops XON/XOFF
(0x11/0x13) and NUL bytes, and pulls out asynchronous ``***`` error lines wherever they appear.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from selfcal.hw.acl.errors import AclErrorEvent, AclProtocolError, split_error
from selfcal.hw.acl.text import IGNORED_BYTES, LEADING_PROMPT, LINE_SPLIT, quote_bytes

__all__ = ["AclReply", "ReplyAssembler"]

_ALLOWED_CONTROL = {0x09, 0x0A, 0x0D}
_PROMPT_ALONE = re.compile(r"^\s*>[\s_]*$")
_PROMPT_SAME_LINE = re.compile(r"^(?P<body>.*?[^\s\-=<>])\s*>[\s_]*$")
_QUESTION = re.compile(
    r"(?:^\s*\d+\s*--\s*\[[^\]]*\]\s*>[\s_]*$)|(?:\(\s*YES\s*/\s*NO\s*\)\s*>[\s_]*$)", re.I
)


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

    MAX_REPLY_BYTES = 65536
    """Cap on one reply: a longer one is a runaway or a wrong baud rate, never an ACL answer."""
    MAX_LINE_CHARS = 1024
    """Cap on one line (ACL prints lines of at most a few dozen characters)."""

    def __init__(self, command: str | None, expect_echo: bool = False):
        self.command = command
        self.expect_echo = bool(expect_echo) and bool(command)
        self.raw = bytearray()
        self._status = self.INCOMPLETE
        self._analysis: dict[str, Any] = {}
        # incremental state: the filtered text not yet split into complete lines, and what the
        # complete lines gave (each line is analysed once: linear time in the reply length)
        self._pending = ""
        self._lines: list[str] = []
        self._errors: list[AclErrorEvent] = []
        self._echoed = False
        self._content_seen = False
        self._want = _norm_cmd(command) if command else None

    def feed(self, data: bytes) -> str:
        """Add received bytes; returns the new status.

        Raises:
            AclProtocolError: the reply exceeds ``MAX_REPLY_BYTES`` or a line ``MAX_LINE_CHARS``.
        """
        if data:
            self.raw += data
            if len(self.raw) > self.MAX_REPLY_BYTES:
                raise AclProtocolError(
                    f"reply to {self.command!r} longer than {self.MAX_REPLY_BYTES} bytes without "
                    f"a prompt: {quote_bytes(bytes(self.raw))}",
                    bytes(self.raw),
                    tuple(self._errors),
                )
            self._pending += bytes(b for b in data if b not in IGNORED_BYTES).decode("latin-1")
            self._analyse()
        return self._status

    @property
    def status(self) -> str:
        return self._status

    @property
    def text(self) -> str:
        """Received text with XON/XOFF/NUL removed (latin-1, so every byte maps to one char)."""
        return bytes(b for b in self.raw if b not in IGNORED_BYTES).decode("latin-1")

    def garbled_bytes(self) -> bytes:
        """Bytes that cannot occur in an ACL reply (non-ASCII or stray control characters)."""
        return bytes(
            b
            for b in self.raw
            if b not in IGNORED_BYTES and (b >= 0x7F or (b < 0x20 and b not in _ALLOWED_CONTROL))
        )

    def _take_line(self, raw_line: str) -> None:
        before, ev = split_error(raw_line)
        if ev is not None:
            self._errors.append(ev)
        line = LEADING_PROMPT.sub("", before).strip()
        if not line:
            return
        if (
            self._want is not None
            and not self._echoed
            and not self._content_seen
            and _norm_cmd(line) == self._want
        ):
            self._echoed = True
            return
        self._content_seen = True
        self._lines.append(line)

    def _analyse(self) -> None:
        # a "\r" ending the pending text may be the first half of "\r\n": taking the line now
        # leaves an empty line after it, which is skipped like any blank line
        parts = LINE_SPLIT.split(self._pending)
        for raw_line in parts[:-1]:
            self._take_line(raw_line)
        tail = parts[-1]
        self._pending = tail
        if len(tail) > self.MAX_LINE_CHARS:
            raise AclProtocolError(
                f"a line of the reply to {self.command!r} is longer than {self.MAX_LINE_CHARS} "
                f"characters: {quote_bytes(bytes(self.raw))}",
                bytes(self.raw),
                tuple(self._errors),
            )
        status = self.INCOMPLETE
        body = ""
        question = None
        same_line = False
        # an error line whose line end has not arrived yet: wait for the rest of it
        tail_has_error = "***" in tail and split_error(tail)[1] is not None
        if not tail_has_error and ">" in tail:
            echo_ok = self._echoed or not self.expect_echo
            if _QUESTION.search(tail):
                status, question = self.COMPLETE, tail.strip()
            elif _PROMPT_ALONE.match(tail):
                if echo_ok:
                    # a prompt that is the very first thing received may be a stale one (the
                    # echo or reply can still follow): confirm it by a quiet period
                    nothing_before = not self._echoed and not self._lines and not self._errors
                    status = self.MAYBE if nothing_before else self.COMPLETE
            else:
                m = _PROMPT_SAME_LINE.match(tail)
                if m and echo_ok:
                    status, same_line = self.MAYBE, True
                    body = LEADING_PROMPT.sub("", m.group("body")).strip()
        self._status = status
        # the complete lines are copied only when asked for (result): copying them on every
        # byte would make the reader quadratic again
        self._analysis = dict(body=body, question=question, same_line=same_line)

    def events(self) -> tuple[AclErrorEvent, ...]:
        """Error events seen so far (complete lines only)."""
        return tuple(self._errors)

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
                tuple(self._errors),
            )
        body = a.get("body", "")
        return AclReply(
            command=self.command or "",
            lines=(*self._lines, body) if body else tuple(self._lines),
            errors=tuple(self._errors),
            echoed=self._echoed,
            question=a.get("question"),
            prompt_same_line=a.get("same_line", False),
            raw=bytes(self.raw),
        )
