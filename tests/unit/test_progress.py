"""The one progress mechanism (selfcal.console.progress.Progress): a bar (drawn by rich) with
done/total and the time left on a terminal, notes above it, one-piece steps with their result;
silent elsewhere for short stages and always with enabled=False (-q)."""

from __future__ import annotations

import io
import re

from selfcal.console import progress
from selfcal.console.progress import Progress, TaskCounts, format_seconds


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def plain(text: str) -> str:
    """``text`` without terminal control sequences (colours, cursor moves, line erases)."""
    return re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text)


def clock(monkeypatch, start=100.0):
    now = [start]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: now[0])
    return now


def test_bar_shows_done_total_and_time_left(monkeypatch):
    now = clock(monkeypatch)
    tty = Tty()
    p = Progress("detect", stream=tty)
    p.start(10)
    now[0] += 4.0
    p.advance(2)  # 2 pieces in 4 s: 8 left at 2 s each
    assert p.state() == "  4.0 s, ~16 s left"
    last = plain(tty.getvalue()).split("\r")[-1]
    assert last.startswith("detect ") and " 2/10   4.0 s, ~16 s left" in last
    p.advance(8)
    p.finish()
    text = plain(tty.getvalue())
    assert text.endswith("\n")
    final = text.rstrip("\n").split("\r")[-1]
    assert "10/10" in final and "left" not in final  # no time left once done


def test_resumed_stage_estimates_from_the_new_pieces_only(monkeypatch):
    now = clock(monkeypatch)
    p = Progress("acquire", stream=Tty())
    p.start(30, done=20)
    assert p.seconds_left() is None
    now[0] += 5.0
    p.advance()
    assert p.seconds_left() == 45.0


def test_notes_go_above_the_bar_and_batches_show_their_counts(monkeypatch):
    now = clock(monkeypatch)
    counts = TaskCounts(4)
    tty = Tty()
    p = Progress("study noise", stream=tty, counts=counts)
    p.start(4)
    now[0] += 10.0
    counts.finish()
    counts.running = 2
    p.advance(note="seed 1: cal 0.1 mm")
    text = plain(tty.getvalue())
    assert "\r  seed 1: cal 0.1 mm\n" in text  # the bar's line erased, the note, the bar again
    assert text.endswith("1/4  10.0 s, 2 running, 0 failed, ~30 s left")
    p.finish()
    plain_stream = io.StringIO()  # not a terminal: the note alone, with the batch state
    q = Progress("study noise", stream=plain_stream, counts=counts)
    q.advance(note="seed 2: failed")
    assert (
        plain_stream.getvalue() == "  [1/4 done, 2 running, 0 failed, ~30 s left] seed 2: failed\n"
    )


def test_step_reports_its_result_and_time(monkeypatch):
    now = clock(monkeypatch)
    tty = Tty()
    p = Progress("calibrate", stream=tty)
    with p.step("camera stage") as st:
        now[0] += 2.5
        st.result("reprojection RMS 0.412 px")
    text = plain(tty.getvalue())
    assert "camera stage ..." in text  # the spinner's line while it runs
    assert text.endswith("camera stage: reprojection RMS 0.412 px (2.5 s)\n")
    plain_stream = io.StringIO()
    p = Progress("calibrate", stream=plain_stream)
    with p.step("quick"):
        now[0] += 0.2  # under a second: nothing off a terminal
    with p.step("slow") as st:
        now[0] += 3.0
        st.result("ok")
    assert plain_stream.getvalue() == "slow: ok (3.0 s)\n"


def test_disabled_progress_prints_nothing(monkeypatch):
    now = clock(monkeypatch)
    tty = Tty()
    p = Progress("detect", stream=tty, enabled=False)
    p.start(3)
    p.advance(note="a note")
    now[0] += 5.0
    p.finish()
    with p.step("homing"):
        now[0] += 5.0
    assert tty.getvalue() == ""


def test_format_seconds():
    assert format_seconds(42.4) == "42 s" and format_seconds(185) == "3 min 05 s"


def test_a_stage_an_error_ends_leaves_no_display_running(monkeypatch):
    """No refresh thread: after an unfinished stage nothing more is written (an error message
    printed after it stays the last line); a step that raises says so."""
    import threading

    clock(monkeypatch)
    tty = Tty()
    before = set(threading.enumerate())
    p = Progress("acquire", stream=tty)
    p.start(5)
    p.advance()
    # no thread of ours (rich's refresh thread): other tests' threads may end meanwhile
    # under xdist, so compare the sets, not the counts
    assert not set(threading.enumerate()) - before
    written = tty.getvalue()
    try:
        with p.step("homing"):
            raise RuntimeError("cable")
    except RuntimeError:
        pass
    assert plain(tty.getvalue()[len(written) :]).endswith("homing: failed (0.0 s)\n")
