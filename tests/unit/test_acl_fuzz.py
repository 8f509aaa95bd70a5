"""Totality of the ACL reply reader and parsers (issue #15): any bytes end in a value or the
protocol's typed error (``AclProtocolError`` / ``AclControllerError``), never another exception;
the reader analyses each line once and caps the reply size."""

from __future__ import annotations

import pytest
from conftest import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from selfcal.hw.acl.errors import (
    AclControllerError,
    AclProtocolError,
    extract_error_events,
    parse_error_line,
)
from selfcal.hw.acl.parsers import parse_listpv, parse_mflag, parse_show_speed, parse_version
from selfcal.hw.acl.reply import AclReply, ReplyAssembler

PARSERS = (parse_listpv, parse_mflag, parse_show_speed, parse_version)
TYPED = (AclProtocolError, AclControllerError)

# bytes drawn mostly from the reply alphabet so the fuzz reaches the parsers' branches
_ALPHABET = b"0123456789 :->*\r\nXYZPRpositonPOSITIONGRUPSEDVAK.()/[]\x00\x11\x13\xff\x07"
_chunks = st.lists(
    st.one_of(
        st.binary(max_size=40),
        st.lists(st.sampled_from(list(_ALPHABET)), max_size=80).map(bytes),
        st.sampled_from(
            [b"1:0  2: 5  3: 13926\r\n", b"X: 5197  Y:0\r\n", b"Position P\r\n", b">", b"\r\n"]
        ),
        st.integers(1, 6000).map(lambda n: b"1:" + b"9" * n + b"\r\n"),
    ),
    max_size=8,
)


def _digits(n: int) -> str:
    return "7" * n


@settings(max_examples=examples(300), deadline=None)
@given(_chunks, st.sampled_from(["LISTPV POSITION", "PRINT MFLAG", "SHOW SPEED", "VER", None]))
def test_any_bytes_end_in_a_reply_or_the_typed_error(chunks, command):
    asm = ReplyAssembler(command)
    try:
        for c in chunks:
            asm.feed(c)
        reply = asm.result()
    except AclProtocolError:
        return
    assert isinstance(reply, AclReply)
    for parse in PARSERS:
        try:
            parse(reply)
        except TYPED:
            pass


@settings(max_examples=examples(300), deadline=None)
@given(st.text(max_size=200), st.integers(0, 6000))
def test_error_lines_are_total(text, n):
    for line in (text, f"*** IMPACT PROTECTION AXIS {_digits(n)}", f"AXIS DISABLED {_digits(n)}"):
        ev = parse_error_line(line)
        assert ev is None or ev.axis is None or ev.axis >= 0
        extract_error_events(line)


@pytest.mark.parametrize("n", [19, 4301, 10000])
def test_huge_integers_are_protocol_errors(n):
    """Python refuses int() of more than 4300 digits with a bare ValueError: the parsers refuse
    numbers longer than 18 digits (int64) first, with the protocol's error."""
    big = _digits(n)
    cases = [
        (parse_listpv, f"1:{big}  2:0"),
        (parse_listpv, f"{big}:0"),
        (parse_listpv, f"1:0\nX: {big}"),
        (parse_mflag, big),
        (parse_show_speed, f"GROUP A SPEED IS: {big}"),
    ]
    for parse, text in cases:
        reply = AclReply("CMD", tuple(text.split("\n")), raw=text.encode())
        with pytest.raises(AclProtocolError, match="digits"):
            parse(reply)
    ev = parse_error_line(f"*** IMPACT PROTECTION AXIS {big}")
    assert ev is not None and ev.kind == "impact_protection" and ev.axis is None


def test_reply_read_byte_by_byte_analyses_each_line_once(monkeypatch):
    """Linear time: a 4 KB reply fed one byte at a time analyses each of its lines once (the
    old reader re-split the whole reply on every byte: 2.6 s for 4 KB; see
    selfcal/benchmarks/timing/acl.py for the time)."""
    calls = []
    original = ReplyAssembler._take_line
    monkeypatch.setattr(
        ReplyAssembler, "_take_line", lambda self, line: (calls.append(line), original(self, line))
    )
    body = "".join(f"{i}:{i * 7}\r\n" for i in range(1, 500))
    data = (body + ">").encode()
    assert len(data) > 4000
    asm = ReplyAssembler(None)
    for i in range(len(data)):
        asm.feed(data[i : i + 1])
    assert asm.status == ReplyAssembler.COMPLETE
    # each line once; a "\r\n" split across two reads adds one empty line, skipped
    assert [c for c in calls if c] == [line for line in body.split("\r\n") if line]
    assert len(calls) <= 2 * 499
    assert len(asm.result().lines) == 499


def test_reply_size_and_line_length_are_capped():
    asm = ReplyAssembler("LISTPV POSITION")
    with pytest.raises(AclProtocolError, match="longer than 1024 characters"):
        asm.feed(b"1" * 1025)
    asm = ReplyAssembler("LISTPV POSITION")
    with pytest.raises(AclProtocolError, match="longer than 65536 bytes"):
        for _ in range(70):
            asm.feed(b"1:0 2:0\r\n" * 110)
