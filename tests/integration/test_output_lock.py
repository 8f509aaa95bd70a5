"""One writer per output folder (#33): two `selfcal run --out same` at once wrote joints.csv with
frames 0-15 twice and exited 4 (the hardware code) for a file race. A command that writes a
folder holds FOLDER/.selfcal.lock (selfcal.io.outlock); a second one says who holds it and exits 2
before it touches anything; a lock whose process is gone is taken over with a warning. An --out
that cannot be a folder is an input error naming it (before: exit 1)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import pytest

from selfcal.cli import main as cli
from selfcal.io.outlock import LOCK_NAME, OutputBusyError, output_lock


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def scenario(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text("[noise]\nrender = false\n[trajectory]\nposes = 6\n[validation]\nposes = 3\n")
    return p


@pytest.mark.parametrize("command", ["run", "acquire"])
def test_a_second_writer_is_refused_naming_the_first(capsys, tmp_path, scenario, command):
    out = tmp_path / "same"
    with output_lock(out, "selfcal run --out same"):
        code, stdout, err = run(capsys, command, scenario, "--out", out, "--quiet")
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]  # nothing touched
    assert code == 2 and stdout == ""
    assert f"--out {out}: another selfcal writes this folder (pid {os.getpid()} on " in err
    assert "`selfcal run --out same`, started 20" in err and " -- wait for it to finish" in err
    assert not (out / LOCK_NAME).exists()  # released by its holder


def test_the_lock_is_held_while_the_command_runs_and_released_after(
    capsys, tmp_path, scenario, monkeypatch
):
    import selfcal.pipeline.run

    seen = []

    def acquire(s, out, **kw):  # what the acquisition finds in its folder
        seen.append(json.loads((out / LOCK_NAME).read_text()))
        raise KeyboardInterrupt  # and the lock is released however the command ends

    monkeypatch.setattr(selfcal.pipeline.run, "run_acquire", acquire)
    code, _, _ = run(capsys, "acquire", scenario, "--out", tmp_path / "ds", "--quiet")
    assert code == 130
    assert seen[0]["pid"] == os.getpid() and seen[0]["host"] == socket.gethostname()
    assert seen[0]["command"] == f"selfcal acquire {scenario} --out {tmp_path / 'ds'} --quiet"
    assert not (tmp_path / "ds" / LOCK_NAME).exists()


def test_a_stale_lock_is_taken_over_with_a_note(capsys, tmp_path):
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    ds = tmp_path / "ds"
    ds.mkdir()
    stale = {"pid": int(gone.stdout), "host": socket.gethostname(),
             "command": "selfcal calibrate ds", "started": "2026-01-01T00:00:00+00:00"}  # fmt: skip
    (ds / LOCK_NAME).write_text(json.dumps(stale))
    code, _, err = run(capsys, "calibrate", ds, "--quiet")
    assert "selfcal: warning: " in err and "took over a stale lock (pid " in err
    assert "`selfcal calibrate ds`, started 2026-01-01T00:00:00+00:00: no longer running" in err
    assert code == 2 and "dataset.json" in err  # then the command's own error: not a dataset
    assert not (ds / LOCK_NAME).exists()


def test_a_lock_of_another_host_is_held(capsys, tmp_path, scenario):
    out = tmp_path / "shared"
    out.mkdir()
    (out / LOCK_NAME).write_text(json.dumps({"pid": 1, "host": "elsewhere", "command": "x",
                                             "started": "now"}))  # fmt: skip
    code, _, err = run(capsys, "acquire", scenario, "--out", out, "--quiet")
    assert code == 2 and "pid 1 on elsewhere" in err and f"remove {out / LOCK_NAME}" in err


@pytest.mark.parametrize("where", ["file", "below_file", "proc"])
def test_an_out_that_cannot_be_a_folder_exits_2_naming_it(capsys, tmp_path, scenario, where):
    (tmp_path / "f").write_text("a file\n")
    out = {"file": tmp_path / "f", "below_file": tmp_path / "f" / "sub" / "ds",
           "proc": "/proc/selfcal-out"}[where]  # fmt: skip
    code, stdout, err = run(capsys, "run", scenario, "--out", out, "--quiet")
    assert code == 2 and stdout == "" and f"--out {out}: " in err, err
    want = {"file": "exists and is not a folder", "below_file": f"{tmp_path / 'f'} is a file",
            "proc": "cannot create the folder"}[where]  # fmt: skip
    assert want in err
    assert (tmp_path / "f").read_text() == "a file\n"


def test_a_living_pid_of_another_process_does_not_keep_a_crashed_lock(tmp_path):
    """A crashed writer's pid taken by a new process (here: this test's parent, alive, started
    at another time) does not hold the lock: its start time differs from the lock's."""
    from selfcal.io.outlock import _start_ticks

    ticks = _start_ticks(os.getppid())
    if ticks is None:
        pytest.skip("no /proc on this system")
    ds = tmp_path / "ds"
    ds.mkdir()
    crashed = {"pid": os.getppid(), "host": socket.gethostname(), "command": "selfcal run",
               "started": "2026-01-01T00:00:00+00:00", "start_ticks": ticks + 1}  # fmt: skip
    (ds / LOCK_NAME).write_text(json.dumps(crashed))
    with output_lock(ds, "selfcal run --out ds") as note:
        assert note is not None and "took over a stale lock" in note
        assert json.loads((ds / LOCK_NAME).read_text())["start_ticks"] == _start_ticks(os.getpid())
    crashed["start_ticks"] = ticks  # the same process: still running, the lock is held
    (ds / LOCK_NAME).write_text(json.dumps(crashed))
    with pytest.raises(OutputBusyError), output_lock(ds, "selfcal run --out ds"):
        pass


def test_import_is_one_writer_per_folder_and_a_refused_import_leaves_no_folder(capsys, tmp_path):
    out = tmp_path / "ds"
    args = ["import", "--images", tmp_path, "--joints", tmp_path / "j.csv", "--joint-units",
            "deg", "--robot", "ur5e", "--target", tmp_path / "board.toml", "--out", out]  # fmt: skip
    with output_lock(out, "selfcal import ... --out ds"):
        code, _, err = run(capsys, *args)
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]  # nothing touched
    assert code == 2 and "another selfcal writes this folder" in err
    assert not out.exists()  # the lock's holder made the folder and removed it, empty
    code, _, err = run(capsys, *args)  # no images: refused, no folder left
    assert code == 2 and "no file matches" in err
    assert not out.exists()
