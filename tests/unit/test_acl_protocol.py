"""The ACL reply reader and parsers against the transcripts of shared/hardware/acl-notes.md,
and the link over ``loop://`` with a scripted controller."""

from __future__ import annotations

import numpy as np
import pytest
import serial

from selfcal.hw.acl.errors import (
    AclConnectionError,
    AclControllerError,
    AclProtocolError,
    AclTimeoutError,
    parse_error_line,
)
from selfcal.hw.acl.link import AclLink, open_serial
from selfcal.hw.acl.parsers import parse_listpv, parse_mflag, parse_show_speed, parse_version
from selfcal.hw.acl.reply import ReplyAssembler

# The LISTPV transcript of the notes, verbatim (prompt + echo on the first line).
LISTPV_NOTES = (
    ">LISTPV POSITION\n"
    "Position POSITION\n"
    "1:0  2: 5  3: 13926  4:0  5:0\n"
    "X: 5197  Y:0  Z: 9963  P: -623  R:-3\n"
    ">"
)


def _bytes(text: str, le: str) -> bytes:
    return text.replace("\n", le).encode("ascii")


def _assemble(cmd: str | None, data: bytes, chunk: int | None = None, expect_echo: bool = False):
    """Feed ``data`` in chunks; return (assembler, statuses seen before the last chunk)."""
    asm = ReplyAssembler(cmd, expect_echo=expect_echo)
    step = chunk or len(data)
    statuses = []
    for i in range(0, len(data), step):
        statuses.append(asm.feed(data[i : i + step]))
    return asm, statuses[:-1]


@pytest.mark.parametrize("le", ["\r\n", "\r", "\n"])
@pytest.mark.parametrize("echo", [True, False])
@pytest.mark.parametrize("chunk", [None, 1, 7])
def test_listpv_transcript(le, echo, chunk):
    text = LISTPV_NOTES if echo else LISTPV_NOTES.split("\n", 1)[1]
    asm, before = _assemble("LISTPV POSITION", _bytes(text, le), chunk)
    assert asm.status == ReplyAssembler.COMPLETE
    # never complete before the final prompt; the notes' leading '>' alone is only "maybe" (a
    # stale prompt is confirmed by a quiet period, which the echo right behind it interrupts)
    assert ReplyAssembler.COMPLETE not in before
    assert all(s == ReplyAssembler.INCOMPLETE for s in before[1:])
    if echo:  # expecting the echo, even the leading '>' is not taken for the end
        asm2, before2 = _assemble("LISTPV POSITION", _bytes(text, le), chunk, expect_echo=True)
        assert asm2.status == ReplyAssembler.COMPLETE
        assert all(s == ReplyAssembler.INCOMPLETE for s in before2)
    reply = asm.result()
    assert reply.echoed is echo
    assert reply.lines == (
        "Position POSITION",
        "1:0  2: 5  3: 13926  4:0  5:0",
        "X: 5197  Y:0  Z: 9963  P: -623  R:-3",
    )
    lp = parse_listpv(reply)
    assert lp.position == "POSITION"
    assert lp.counts == {1: 0, 2: 5, 3: 13926, 4: 0, 5: 0}
    np.testing.assert_allclose(lp.xyz_mm, [519.7, 0.0, 996.3])
    assert lp.pitch_deg == pytest.approx(-62.3) and lp.roll_deg == pytest.approx(-0.3)


@pytest.mark.parametrize("le", ["\r\n", "\r"])
@pytest.mark.parametrize("echo", [True, False])
def test_prompt_on_the_same_line(le, echo):
    text = "Position POSITION\n1:0 2:1791 3:2746 4:0 5:-1\nX: 5197  Y:0  Z: 9963  P: -623  R:-201 >"
    if echo:
        text = "LISTPV POSITION\n" + text
    asm, before = _assemble("LISTPV POSITION", _bytes(text, le), 3)
    assert asm.status == ReplyAssembler.MAYBE  # complete once nothing more arrives
    assert ReplyAssembler.COMPLETE not in before
    reply = asm.result()
    assert reply.prompt_same_line
    lp = parse_listpv(reply)
    assert lp.counts == {1: 0, 2: 1791, 3: 2746, 4: 0, 5: -1}
    assert lp.roll_deg == pytest.approx(-20.1)


def test_gt_inside_replies_does_not_end_them():
    # SHOW DIN: "1 -> 16: ..." contains '>' after '-'; fed byte by byte it never completes early
    text = "SHOW DIN\r\n 1 -> 16: 0 1 0 0 1 0 0 0 0 0 0 0 0 0 0 1\r\n17 -> 32: 0 0 0 0\r\n>"
    asm, before = _assemble("SHOW DIN", text.encode(), 1)
    assert all(s == ReplyAssembler.INCOMPLETE for s in before)
    assert asm.status == ReplyAssembler.COMPLETE
    assert asm.result().lines == (
        "1 -> 16: 0 1 0 0 1 0 0 0 0 0 0 0 0 0 0 1",
        "17 -> 32: 0 0 0 0",
    )


@pytest.mark.parametrize(
    "question", ["1 -- [100] >", "  3 --[-2511]>", "DELETE ALL PROGRAMS ?? (YES/NO)>"]
)
def test_questions_are_not_prompts(question):
    text = f"SETPV P1\r\n{question}"
    asm, before = _assemble("SETPV P1", text.encode(), 1)
    assert asm.status == ReplyAssembler.COMPLETE
    assert ReplyAssembler.MAYBE not in before  # "1 -- [100]" is never taken for a value + prompt
    reply = asm.result()
    assert reply.question == question.strip()
    assert reply.lines == ()


def test_xon_xoff_and_nul_bytes_are_ignored():
    clean = _bytes(LISTPV_NOTES, "\r\n")
    dirty = bytearray()
    for i, b in enumerate(clean):
        dirty.append(b)
        if i % 5 == 0:
            dirty += bytes([0x13, 0x11])
        if i % 11 == 0:
            dirty.append(0x00)
    a1, _ = _assemble("LISTPV POSITION", clean)
    a2, _ = _assemble("LISTPV POSITION", bytes(dirty), 4)
    assert a2.status == ReplyAssembler.COMPLETE
    assert a1.result().lines == a2.result().lines


@pytest.mark.parametrize("where", ["before_echo", "between_lines", "mid_line", "before_prompt"])
def test_async_error_lines_interleaved(where):
    err = "*** IMPACT PROTECTION axis 2"
    lines = LISTPV_NOTES.split("\n")
    if where == "before_echo":
        lines.insert(0, err)
    elif where == "between_lines":
        lines.insert(2, err)
    elif where == "before_prompt":
        lines.insert(4, err)
    else:  # the error starts in the middle of the header line
        lines[1] = lines[1] + " " + err
    asm, _ = _assemble("LISTPV POSITION", "\r\n".join(lines).encode(), 2)
    assert asm.status == ReplyAssembler.COMPLETE
    reply = asm.result()
    assert [(e.kind, e.axis) for e in reply.errors] == [("impact_protection", 2)]
    assert all("***" not in line for line in reply.lines)
    assert reply.echoed  # the echo is recognised even after an error line
    # the interleaved asynchronous error does not spoil the values around it
    assert parse_listpv(reply).counts == {1: 0, 2: 5, 3: 13926, 4: 0, 5: 0}


def test_error_line_without_its_line_end_is_waited_for():
    asm = ReplyAssembler("PRINT MFLAG")
    assert asm.feed(b"PRINT MFLAG\r\n31\r\n*** OUT OF RANGE axis 1 >") == ReplyAssembler.INCOMPLETE
    assert asm.feed(b"\r\n>") == ReplyAssembler.COMPLETE
    assert [e.kind for e in asm.result().errors] == ["out_of_range"]


def test_stale_prompt_before_echo_is_ignored_when_echo_is_expected():
    asm = ReplyAssembler("PRINT MFLAG", expect_echo=True)
    assert asm.feed(b">") == ReplyAssembler.INCOMPLETE
    assert asm.feed(b"PRINT MFLAG\r\n0\r\n>") == ReplyAssembler.COMPLETE
    assert parse_mflag(asm.result()) == 0
    # without the expectation a lone first '>' is only "maybe": what follows still counts
    asm = ReplyAssembler("PRINT MFLAG")
    assert asm.feed(b">") == ReplyAssembler.MAYBE
    assert asm.feed(b"PRINT MFLAG\r\n") == ReplyAssembler.INCOMPLETE
    assert asm.feed(b"0\r\n>") == ReplyAssembler.COMPLETE
    assert parse_mflag(asm.result()) == 0


def test_garbled_reply_raises_and_quotes_the_bytes():
    raw = b"PRINT MFLAG\r\n3\xb1\r\n>"
    asm, _ = _assemble("PRINT MFLAG", raw)
    with pytest.raises(AclProtocolError) as ei:
        asm.result()
    assert repr(raw) in str(ei.value)
    assert ei.value.raw == raw


# ---- parsers ------------------------------------------------------------------------------------


def _reply(cmd: str, body: str):
    asm, _ = _assemble(cmd, (body + "\r\n>").encode())
    assert asm.status == ReplyAssembler.COMPLETE
    return asm.result()


def test_listpv_extra_axes_negative_values_and_no_header():
    r = _reply("LISTPV P1", "1:-12770 2:  10216 3:-3 4:2511 5:-2511 6:0 7:12 8:-4")
    lp = parse_listpv(r)
    assert lp.position is None
    assert lp.counts == {1: -12770, 2: 10216, 3: -3, 4: 2511, 5: -2511, 6: 0, 7: 12, 8: -4}
    np.testing.assert_array_equal(lp.axis_counts(5), [-12770, 10216, -3, 2511, -2511])
    assert lp.xyz_mm is None
    with pytest.raises(AclProtocolError, match=r"axes \[9\]"):
        lp.axis_counts(9)


@pytest.mark.parametrize(
    "body, match",
    [
        ("Position P1\r\n1:0 2:5 3:1 1:4", "repeats"),
        ("Position P1\r\n1:02:5 3:1", "unexpected line"),  # lost whitespace: ambiguous, refused
        ("Position P1\r\nX: 1 Y: 2", "no joint counts"),
        ("Position P1\r\n2:0 3:0", "not consecutive"),
        ("Position P1\r\n1:0 2:5\r\nHELLO", "unexpected line"),
    ],
)
def test_listpv_malformed(body, match):
    r = _reply("LISTPV P1", body)
    with pytest.raises(AclProtocolError, match=match) as ei:
        parse_listpv(r)
    assert repr(r.raw)[:20] in str(ei.value) or "unexpected line" in str(ei.value)


def test_listpv_no_position_assigned():
    r = _reply("LISTPV P1", "NO POSITION ASSIGNED TO POINT P1")
    with pytest.raises(AclControllerError) as ei:
        parse_listpv(r)
    assert ei.value.event.kind == "no_position" and ei.value.event.position == "P1"


def test_mflag_speed_version():
    assert parse_mflag(_reply("PRINT MFLAG", "31")) == 31
    assert parse_mflag(_reply("PRINT MFLAG", " 0")) == 0
    with pytest.raises(AclProtocolError):
        parse_mflag(_reply("PRINT MFLAG", "3 1"))
    assert parse_show_speed(_reply("SHOW SPEED", "GROUP A SPEED IS: 40\r\nO.K.")) == {"A": 40}
    assert parse_show_speed(
        _reply("SHOW SPEED", "GROUP A SPEED IS: 40\r\nGROUP B SPEED IS:7\r\nO.K.")
    ) == {"A": 40, "B": 7}
    with pytest.raises(AclProtocolError):
        parse_show_speed(_reply("SHOW SPEED", "O.K."))
    v = parse_version(_reply("VER", "ESHED ROBOTEC\r\nVERSION: 1.42\r\nDATE : 21/07/91"))
    assert (v.version, v.date, v.lines[0]) == ("1.42", "21/07/91", "ESHED ROBOTEC")


@pytest.mark.parametrize(
    "line, kind, axis",
    [
        ("*** IMPACT PROTECTION axis 3", "impact_protection", 3),
        ("*** OUT OF RANGE axis 1", "out_of_range", 1),
        ("*** THERMIC OVERLOAD axis 5", "thermic_overload", 5),
        ("*** TRAJECTORY ERROR !", "trajectory_error", None),
        ("*** UPPER LIMIT AXIS 2", "upper_limit", 2),
        ("*** LOWER LIMIT AXIS 4", "lower_limit", 4),
        ("*** HOME FAILURE AXIS 2", "home_failure", 2),
        ("NO POSITION ASSIGNED TO POINT PA", "no_position", None),
        ("BAD POINT COORDINATE", "bad_point_coordinate", None),
        ("BAD CARTESIAN POINT", "bad_cartesian_point", None),
        ("AXIS DISABLED", "axis_disabled", None),
        ("*** SOMETHING NEW", "controller_error", None),
        (">*** IMPACT PROTECTION axis 1", "impact_protection", 1),
    ],
)
def test_error_lines(line, kind, axis):
    ev = parse_error_line(line)
    assert ev is not None and ev.kind == kind and ev.axis == axis
    assert ev.latching == (line.lstrip(">").startswith("***") or kind == "axis_disabled")


@pytest.mark.parametrize("line", ["Position POSITION", "1 -> 16: 0 1", "O.K.", "CONTROL ENABLED"])
def test_non_error_lines(line):
    assert parse_error_line(line) is None


# ---- the link over loop:// ----------------------------------------------------------------------


class ScriptedPort:
    """``loop://`` with a scripted controller: writing a command puts (echo +) its reply into the
    loop. ``script`` maps a command to a list of replies (one per call; the last one repeats);
    ``None`` means no reply at all."""

    def __init__(self, script: dict, echo: bool = True, le: str = "\r\n"):
        self.loop = serial.serial_for_url("loop://", timeout=0.01)
        self.script = {k: list(v) for k, v in script.items()}
        self.echo = echo
        self.le = le
        self.written: list[bytes] = []
        self._buf = b""

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        self._buf += data
        while b"\r" in self._buf:
            line, self._buf = self._buf.split(b"\r", 1)
            cmd = line.replace(b"\x01", b"").decode()
            replies = self.script.get(cmd, [""])
            reply = replies.pop(0) if len(replies) > 1 else replies[0]
            if reply is None:
                continue
            out = (cmd + self.le if self.echo else "") + reply.replace("\n", self.le)
            self.loop.write(out.encode("latin-1"))
        return len(data)

    def __getattr__(self, name):
        return getattr(self.loop, name)


def test_open_serial_urls():
    port = open_serial("loop://")
    assert port.is_open and port.baudrate == 9600 and port.xonxoff
    port.close()
    with pytest.raises(AclConnectionError, match="/dev/does-not-exist"):
        open_serial("/dev/does-not-exist")


@pytest.mark.parametrize("echo", [True, False])
@pytest.mark.parametrize("le", ["\r\n", "\r"])
def test_link_command_and_query(echo, le):
    port = ScriptedPort(
        {
            "LISTPV POSITION": ["Position POSITION\n1:0  2: 5  3: 13926  4:0  5:0\nX: 1  Y:0 >"],
            "PRINT MFLAG": ["31\n>"],
            "": [">"],
        },
        echo=echo,
        le=le,
    )
    link = AclLink(port, settle_s=0.02)
    lp = link.query("LISTPV POSITION", parse_listpv)
    assert lp.counts[3] == 13926 and lp.cartesian == {"X": 1, "Y": 0}
    assert link.query("PRINT MFLAG", parse_mflag) == 31
    assert port.written == [b"LISTPV POSITION\r", b"PRINT MFLAG\r"]


def test_link_query_retries_a_garbled_reply_once():
    port = ScriptedPort({"PRINT MFLAG": ["3\xb11\n>", "0\n>"], "": [">"]})
    link = AclLink(port)
    assert link.query("PRINT MFLAG", parse_mflag, retries=2) == 0
    assert port.written.count(b"PRINT MFLAG\r") == 2
    assert b"\r" in port.written  # resynchronised between the attempts


def test_link_query_gives_up_after_bounded_retries_with_the_bytes():
    port = ScriptedPort({"PRINT MFLAG": ["junk\n>"], "": [">"]})
    link = AclLink(port)
    with pytest.raises(AclProtocolError, match=r"after 3 attempts") as ei:
        link.query("PRINT MFLAG", parse_mflag, retries=2)
    assert b"junk" in ei.value.raw
    assert port.written.count(b"PRINT MFLAG\r") == 3


def test_link_timeout_quotes_partial_bytes_and_commands_are_not_retried():
    port = ScriptedPort({"MOVE P1": ["WAIT"], "": [None]})
    link = AclLink(port, query_timeout_s=0.15)
    with pytest.raises(AclTimeoutError, match=r"b'MOVE P1\\r\\nWAIT'"):
        link.command("MOVE P1")
    assert port.written.count(b"MOVE P1\r") == 1


def test_link_abort_sends_ctrl_a_then_clrbuf_first():
    port = ScriptedPort({"CLRBUF": [">"], "": [">"]})
    link = AclLink(port)
    link._dirty = True  # even after a bad exchange, nothing (no resync CR) precedes the abort
    assert link.abort() == []
    assert port.written[:2] == [b"\x01", b"CLRBUF\r"]
    assert list(link.tx_log)[:2] == [b"\x01", b"CLRBUF\r"]


def test_link_collects_unsolicited_errors_before_a_command():
    port = ScriptedPort({"PRINT MFLAG": ["0\n>"]})
    port.loop.write(b"\r\n*** IMPACT PROTECTION axis 2\r\n")  # printed while nobody asked
    link = AclLink(port)
    assert link.query("PRINT MFLAG", parse_mflag) == 0
    evs = link.pop_events()
    assert [(e.kind, e.axis) for e in evs] == [("impact_protection", 2)]
    assert link.pop_events() == []


def test_link_rejects_multi_line_commands():
    link = AclLink(ScriptedPort({}))
    with pytest.raises(ValueError, match="one line"):
        link.command("MOVE P1\rMOVE P2")


@pytest.mark.parametrize("where", ["write", "flush", "read", "in_waiting"])
def test_link_failures_become_connection_errors(where):
    """A vanished pty raises termios.error from tcdrain (not an OSError); a socket raises
    SerialException; both must surface as AclConnectionError."""
    import termios

    class Broken(ScriptedPort):
        def write(self, data):
            if where == "write":
                raise serial.SerialException("write failed: [Errno 5] Input/output error")
            return super().write(data)

        def flush(self):
            if where == "flush":
                raise termios.error(5, "Input/output error")

        def read(self, n=1):
            if where == "read":
                raise serial.SerialException("read failed: socket disconnected")
            return self.loop.read(n)

        @property
        def in_waiting(self):
            if where == "in_waiting":
                raise OSError(5, "Input/output error")
            return self.loop.in_waiting

    link = AclLink(Broken({"VER": ["ESHED ROBOTEC\n>"]}), query_timeout_s=0.2)
    with pytest.raises(AclConnectionError, match="serial link lost"):
        link.command("VER")
    problems = link.abort()
    if where in ("write", "flush"):
        assert len(problems) == 2  # both abort writes attempted, both failed
    assert list(link.tx_log)[-2:] == [b"\x01", b"CLRBUF\r"]
