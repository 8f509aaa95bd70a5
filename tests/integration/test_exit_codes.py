"""`selfcal` exit codes (README "Exit codes"): 2 bad input, 3 data that cannot determine the
calibration, 1 an internal error, 130 Ctrl-C; each failure prints one line
`selfcal: error: <what> -- <fix>` and no traceback unless -v.

The hardware fault (exit code 4) is tested against the ACL emulator in test_acl_robot.py
(test_cli_hardware_fault_exits_4).
"""

from __future__ import annotations

import json
import shutil

import pytest
from analytic_dataset import plan_same_postures

from selfcal.cli import main as cli
from selfcal.config.scenario import load_scenario
from selfcal.errors import EstimationError, HardwareError, InputError, SelfCalError
from selfcal.pipeline.run import run_acquire


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_kinds_carry_their_codes():
    assert (InputError.exit_code, EstimationError.exit_code, HardwareError.exit_code) == (2, 3, 4)
    # every class the project raises on purpose has the one root
    from selfcal.calibration.field.calibrate import CalibrationError
    from selfcal.config.scenario import ConfigError
    from selfcal.hw.acl.errors import AclControllerError
    from selfcal.io.calibration import CalibrationFileError
    from selfcal.robot.definition import RobotDefinitionError

    assert issubclass(ConfigError, InputError) and issubclass(RobotDefinitionError, InputError)
    assert issubclass(CalibrationError, EstimationError) and issubclass(
        AclControllerError, HardwareError
    )
    assert CalibrationFileError.exit_code == 2 and issubclass(CalibrationFileError, InputError)
    assert all(issubclass(c, SelfCalError) for c in (ConfigError, CalibrationError))


def test_bad_scenario_key_exits_2(capsys, tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[camera]\nfocal_px = 800.0\n")
    code, out, err = run(capsys, "run", cfg, "--out", tmp_path / "run", "--quiet")
    assert code == 2 and out == ""
    assert err.startswith("selfcal: error: ") and "focal_px" in err and str(cfg) in err
    assert len(err.splitlines()) == 1 and " -- " in err  # the fix on the same line
    assert not (tmp_path / "run").exists()


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    """6 postures on the analytic path (detections, no rendering)."""
    out = tmp_path_factory.mktemp("exit") / "ds"
    s = load_scenario(
        overrides={
            "noise": {"render": False},
            "trajectory": {"poses": 6},
            "validation": {"poses": 3},
        }
    )
    run_acquire(s, out, quiet=True)
    return out


def _keep_rows(src, dst, keep):
    shutil.copytree(src, dst)
    for name in ("joints.csv", "detections.csv"):
        lines = (dst / name).read_text().splitlines()
        rows = [r for r in lines[1:] if keep(int(r.split(",")[0]))]
        (dst / name).write_text("\n".join([lines[0], *rows]) + "\n")
    return dst


def test_too_few_postures_exits_3(capsys, small_dataset, tmp_path):
    ds = _keep_rows(small_dataset, tmp_path / "few", lambda i: i < 3)
    code, out, err = run(capsys, "calibrate", ds, "--quiet")  # rows removed: named (#15)
    assert code == 2 and "frames 3, 4, 5 of the 6 planned have no row" in err
    code, out, err = run(capsys, "calibrate", ds, "--quiet", "--allow-missing-frames")
    assert code == 3 and out == ""
    assert err.startswith("selfcal: error: ") and "at least 6" in err
    assert not (ds / "calibration.json").exists()


def test_degenerate_postures_exit_3(capsys, small_dataset, tmp_path):
    """Every frame at the first posture: the optical axes cannot determine the camera."""
    ds = tmp_path / "same"
    shutil.copytree(small_dataset, ds)
    lines = (ds / "joints.csv").read_text().splitlines()
    first = lines[1].split(",")[1:]
    # the same posture, each row 0.001 deg apart in the last joint (equal rows would be named as
    # copies, #15): the axes still meet in one point
    rows = [",".join([r.split(",")[0], *first[:-1], f"{float(first[-1]) + k * 1e-3:.6f}"])
            for k, r in enumerate(lines[1:])]  # fmt: skip
    (ds / "joints.csv").write_text("\n".join([lines[0], *rows]) + "\n")
    plan_same_postures(ds, rows)
    code, _, err = run(capsys, "calibrate", ds, "--quiet")
    assert code == 3 and err.startswith("selfcal: error: ")


def test_damaged_calibration_exits_2_with_the_fix(capsys, small_dataset, tmp_path):
    ds = tmp_path / "damaged"
    shutil.copytree(small_dataset, ds)
    (ds / "calibration.json").write_text(json.dumps({"format": "something-else"}))
    code, out, err = run(capsys, "export", ds, "--format", "urdf", "--out", tmp_path / "r.urdf")
    assert code == 2 and out == ""
    assert err.startswith("selfcal: error: ") and "something-else" in err


def test_internal_error_exits_1_with_the_debug_hint(capsys, monkeypatch):
    def boom(args):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(cli, "cmd_fk", boom)
    monkeypatch.delenv("SELFCAL_DEBUG", raising=False)
    code, _, err = run(capsys, "fk", "--joints", "0,0,0,0,0")
    assert code == 1 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("selfcal: error: internal error ZeroDivisionError: division by zero")
    assert "-v for the traceback" in err
    code, _, err = run(capsys, "fk", "--joints", "0,0,0,0,0", "-v")
    assert code == 1 and "Traceback (most recent call last)" in err and "in boom" in err
    monkeypatch.setenv("SELFCAL_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        cli.main(["fk", "--joints", "0,0,0,0,0"])


def test_ctrl_c_exits_130(capsys, monkeypatch):
    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "cmd_fk", interrupted)
    code, _, err = run(capsys, "fk", "--joints", "0,0,0,0,0")
    assert code == 130 and "interrupted" in err


@pytest.mark.parametrize(
    "rerun",
    [False, pytest.param(True, marks=pytest.mark.slow)],  # the rerun calibrates: ~4 s
)
def test_ctrl_c_in_run_names_the_command_that_resumes(capsys, monkeypatch, tmp_path, rerun):
    """The message said "stopped at frame 3 of 12: . ... continue with selfcal acquire CONFIG
    --out ... --resume": no reason, a placeholder, and not the `run` that resumes."""
    import shlex

    from selfcal.pipeline import run as pipeline

    scenario = tmp_path / "quick.toml"
    scenario.write_text(
        "[noise]\nrender = false\n[trajectory]\nposes = 10\n[validation]\nposes = 5\n"
    )
    real_open = pipeline.open_robot

    def open_robot(*a, **k):
        robot, hooks = real_open(*a, **k)
        move, moves = robot.move_to, []

        def move_to(q):
            moves.append(q)
            if len(moves) == 4:
                raise KeyboardInterrupt
            move(q)

        robot.move_to = move_to
        return robot, hooks

    monkeypatch.setattr(pipeline, "open_robot", open_robot)
    out = tmp_path / "run dir"
    code, _, err = run(capsys, "run", scenario, "--out", out)
    assert code == 130
    assert "stopped at frame 3 of 10: interrupted (Ctrl-C). 3 frames are kept" in err
    command = err.split("continue with `")[1].split("`")[0]
    assert command == f"selfcal run {scenario} --out '{out}'"
    if not rerun:
        return
    monkeypatch.setattr(pipeline, "open_robot", real_open)
    code, _, err = run(capsys, *shlex.split(command)[1:], "--quiet")
    assert code == 0, err


def test_fix_follows_the_message_on_one_line(capsys, monkeypatch):
    def bad(args):
        raise InputError("the thing is wrong", fix="do the other thing")

    monkeypatch.setattr(cli, "cmd_fk", bad)
    code, _, err = run(capsys, "fk", "--joints", "0,0,0,0,0")
    assert code == 2
    assert err.splitlines() == ["selfcal: error: the thing is wrong -- do the other thing"]
    code, _, err = run(capsys, "-v", "fk", "--joints", "0,0,0,0,0")  # -v: with the traceback
    assert code == 2 and "Traceback" in err
    assert err.splitlines()[-1] == "selfcal: error: the thing is wrong -- do the other thing"


KINDS = {"InputError": 2, "OutputError": 2, "EstimationError": 3, "SolverError": 3,
         "HardwareError": 4, "UsageError": 1, "UsageTypeError": 1, "InternalError": 1}  # fmt: skip


def test_every_kind_has_a_code_here():
    import selfcal.errors as errors

    kinds = {n for n in errors.__all__ if isinstance(getattr(errors, n), type)
             and issubclass(getattr(errors, n), SelfCalError) and n != "SelfCalError"}  # fmt: skip
    assert kinds == set(KINDS)


@pytest.mark.parametrize(("kind", "code"), KINDS.items())
def test_each_kind_exits_with_its_code(capsys, monkeypatch, kind, code):
    """The command line maps every kind of the root to its exit code; a bug's kind (code 1) is
    printed as an internal error with the debug hint, the others as the message alone."""
    import selfcal.errors as errors

    cls = getattr(errors, kind)
    assert kind in errors.__all__ and issubclass(cls, SelfCalError) and cls.exit_code == code

    def fail(args):
        raise cls("the thing is wrong")

    monkeypatch.setattr(cli, "cmd_fk", fail)
    monkeypatch.delenv("SELFCAL_DEBUG", raising=False)
    got, out, err = run(capsys, "fk", "--joints", "0,0,0,0,0")
    assert got == code and out == "" and len(err.splitlines()) == 1
    if code == 1:
        assert err.startswith(f"selfcal: error: internal error {kind}: the thing is wrong -- a bug")
    else:
        assert err == "selfcal: error: the thing is wrong\n"


def test_usage_errors_exit_2_in_the_same_style(capsys):
    code, out, err = run(capsys, "fk")  # --joints is required
    assert code == 2 and out == ""
    last = err.splitlines()[-1]
    assert last.startswith("selfcal: error: the following arguments are required: --joints")
    assert last.endswith("-- see `selfcal fk --help`")


def test_an_option_of_another_command_is_named_with_its_command(capsys, tmp_path):
    # an option of `selfcal identify` (tracker rows) given to `selfcal calibrate`: the error said
    # "unrecognized arguments: ... -- see `selfcal --help`", under the top-level usage, and
    # named neither command (issue 29's `--spread N` was such an option; calibrate has it now)
    code, out, err = run(capsys, "calibrate", tmp_path, "--hold", "beta1")
    assert code == 2 and out == ""
    assert err.startswith("usage: selfcal calibrate ")
    last = err.splitlines()[-1]
    assert last.startswith("selfcal: error: unrecognized arguments: --hold beta1")
    assert "`--hold` is an option of `selfcal identify`" in last
    assert last.endswith("-- see `selfcal calibrate --help`")
    # an option no command has gets no such note; a nested command names itself
    code, _, err = run(capsys, "hw", "joints", "--no-such-option")
    last = err.splitlines()[-1]
    assert code == 2 and "is an option of" not in last
    assert last.endswith("-- see `selfcal hw joints --help`")


def test_python_warnings_become_counted_log_lines(capsys, monkeypatch):
    import warnings

    from selfcal.errors import SelfCalWarning

    def warn(args):
        warnings.warn("the first thing", SelfCalWarning, stacklevel=1)
        warnings.warn("the second thing", RuntimeWarning, stacklevel=1)
        warnings.warn("the first thing", SelfCalWarning, stacklevel=1)  # repeated: once
        return 0

    monkeypatch.setattr(cli, "cmd_fk", warn)
    with pytest.warns(SelfCalWarning, match="first"), pytest.warns(RuntimeWarning, match="second"):
        code, out, err = run(capsys, "fk", "--joints", "0,0,0,0,0")
    assert code == 0 and out == ""
    assert err.splitlines() == [
        "selfcal: warning: the first thing",
        "selfcal: warning: the second thing [RuntimeWarning]",
        err.splitlines()[-1],
    ]
    assert err.splitlines()[-1].startswith("selfcal: done in ")
    assert err.splitlines()[-1].endswith("nothing written; 2 warnings")
