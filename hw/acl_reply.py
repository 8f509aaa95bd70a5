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

from hw.acl_errors import AclErrorEvent, AclProtocolError, split_error
from hw.acl_text import IGNORED_BYTES, LEADING_PROMPT, LINE_SPLIT, quote_bytes

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
        return bytes(b for b in self.raw if b not in IGNORED_BYTES).decode("latin-1")

    def garbled_bytes(self) -> bytes:
        """Bytes that cannot occur in an ACL reply (non-ASCII or stray control characters)."""
        return bytes(
            b
            for b in self.raw
            if b not in IGNORED_BYTES and (b >= 0x7F or (b < 0x20 and b not in _ALLOWED_CONTROL))
        )

    def _analyse(self) -> None:
        text = self.text
        parts = LINE_SPLIT.split(text)
        complete_lines, tail = parts[:-1], parts[-1]
        want = _norm_cmd(self.command) if self.command else None
        lines: list[str] = []
        errors: list[AclErrorEvent] = []
        echoed = False
        content_seen = False
        for raw_line in complete_lines:
            before, ev = split_error(raw_line)
            if ev is not None:
                errors.append(ev)
            line = LEADING_PROMPT.sub("", before).strip()
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
        tail_has_error = "***" in tail and split_error(tail)[1] is not None
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
                    body = LEADING_PROMPT.sub("", m.group("body")).strip()
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
