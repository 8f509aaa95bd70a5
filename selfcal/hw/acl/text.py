"""ACL text on the wire: the control bytes, line ends, the prompt, and received bytes quoted in
error messages. Shared by the reply reader (``selfcal.hw.acl.reply``), the error-line recogniser
(``selfcal.hw.acl.errors``) and the link (``selfcal.hw.acl.link``).
"""

from __future__ import annotations

import re

__all__ = [
    "CTRL_A",
    "XON",
    "XOFF",
    "IGNORED_BYTES",
    "LINE_SPLIT",
    "LEADING_PROMPT",
    "quote_bytes",
    "MAX_INT_DIGITS",
]

CTRL_A = 0x01
XON = 0x11
XOFF = 0x13
IGNORED_BYTES = bytes([0x00, XON, XOFF])
"""Bytes dropped wherever they appear in a reply: NUL and the XON/XOFF flow control."""

MAX_INT_DIGITS = 18
"""Most digits an ACL integer can have (encoder counts, tenths, axis numbers fit in 64 bits); the
reply parsers treat a longer number as garbled instead of converting it (Python refuses
conversions above 4300 digits with a bare ``ValueError``)."""

LINE_SPLIT = re.compile(r"\r\n|\r|\n")
LEADING_PROMPT = re.compile(r"^\s*>+\s*")


def quote_bytes(raw: bytes, limit: int = 400) -> str:
    """``repr`` of received bytes for error messages, shortened in the middle if long."""
    raw = bytes(raw)
    if len(raw) <= limit:
        return repr(raw)
    half = limit // 2
    return f"{raw[:half]!r} ... ({len(raw) - 2 * half} bytes) ... {raw[-half:]!r}"
