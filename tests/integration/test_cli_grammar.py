"""One grammar for the command line (#16, docs/cli.md): positional inputs, optional --out with a
stated default, --robot/--rrd with their old spellings as deprecated aliases, --json on the
commands that print results, fk --calibration, and the last line naming what was written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from selfcal.cli.main import main
from selfcal.config.scenario import DEFAULT_ROBOT, load_scenario

QUICK = "[noise]\nrender = false\n[trajectory]\nposes = 8\n[validation]\nposes = 4\n"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """A folder with an 8-posture analytic scenario (a run of it takes about 2 s)."""
    root = tmp_path_factory.mktemp("grammar")
    cfg = root / "quick.toml"
    cfg.write_text(QUICK)
    return root, cfg


def test_default_robot_is_the_default_scenarios(capsys):
    assert load_scenario().robot.model == DEFAULT_ROBOT
    code, out, _ = run(capsys, "fk", "--joints", "0,0,0,0,0")
    assert code == 0 and json.loads(out)["model"] == DEFAULT_ROBOT


def test_old_spelling_still_works_and_warns(capsys):
    code, out, err = run(capsys, "fk", "--model", "ur5e", "--joints", "0,0,0,0,0,0")
    assert code == 0 and json.loads(out)["model"] == "ur5e"
    assert "selfcal: warning: --model is deprecated and will be removed: use --robot" in err
    assert err.splitlines()[-1].endswith("1 warning")


@pytest.mark.slow  # over 2 s on 2 cores: the default tier keeps to ~90 s
def test_run_json_calibrate_json_and_fk_with_the_calibration(quick_run, capsys, monkeypatch):
    root, cfg = quick_run
    monkeypatch.chdir(root)  # --out defaults to runs/<scenario file name>
    code, out, err = run(capsys, "run", cfg, "--json", "-q")
    assert code == 0
    doc = json.loads(out)  # stdout is the JSON alone; the summary line went to stderr
    assert doc["out"] == "runs/quick" and doc["robot_model"] == DEFAULT_ROBOT
    assert doc["validation"]["poses"] == 4 and doc["reprojection_rms_px"] > 0
    last = err.splitlines()[-1]
    assert last.startswith("selfcal: wrote runs/quick/ (") and "calibration.json" in last

    code, out, err = run(capsys, "calibrate", "runs/quick", "--json")
    assert code == 0 and json.loads(out)["calibration"] == "runs/quick/calibration.json"
    assert err.splitlines()[-1].startswith("selfcal: wrote runs/quick/calibration.json in ")

    q = "10,-20,30,-40,5"
    _, nominal, _ = run(capsys, "fk", "--joints", q)
    code, calibrated, _ = run(capsys, "fk", "--joints", q, "--calibration", "runs/quick")
    assert code == 0
    a, b = json.loads(nominal), json.loads(calibrated)
    assert b["calibration"] == "runs/quick" and "tool tip" in b["frame"]
    # the injected errors (1 mm, 0.5 deg) move the tool tip by millimetres, not metres
    d = np.linalg.norm(np.subtract(a["xyz_mm"], b["xyz_mm"]))
    assert 0.1 < d < 50.0
    code, _, err = run(
        capsys, "fk", "--joints", q, "--calibration", "runs/quick", "--robot", "ur5e"
    )
    assert code == 2 and "contradicts the calibration's robot" in err

    # export without --out: next to the calibration, named by the format
    code, out, _ = run(capsys, "export", "runs/quick", "--format", "toml")
    assert code == 0 and json.loads(out)["out"] == "runs/quick/calibrated.toml"
    code, _, err = run(capsys, "export", "runs/quick")
    assert code == 2 and "give --format" in err


def test_renamed_options_land_in_the_new_names():
    from selfcal.cli.main import build_parser

    p = build_parser()
    args = p.parse_args(["run", "--rerun", "x.rrd"])
    assert args.rrd == "x.rrd" and "--rerun is deprecated" in args.deprecated[0]
    args = p.parse_args(["render", "--config", "s.toml", "--joints", "0,0,0,0,0"])
    assert args.scenario == "s.toml" and args.out == "render"
    args = p.parse_args(["render", "s.toml", "--joints", "0,0,0,0,0"])
    assert args.scenario == "s.toml" and not getattr(args, "deprecated", None)
    args = p.parse_args(["montecarlo", "--config", "s.toml"])
    assert args.scenario == "s.toml" and args.out is None  # runs/montecarlo, set by the command
    args = p.parse_args(["hw", "joints", "--port", "x", "--model", "er4u-paper"])
    assert args.robot == "er4u-paper"
    args = p.parse_args(["-q", "calibrate", "ds"])
    assert args.quiet is True and args.verbose is False
    args = p.parse_args(["calibrate", "ds", "-v"])
    assert args.quiet is False and args.verbose is True


def test_spawn_without_rrd_is_bad_input(quick_run, capsys):
    root, cfg = quick_run
    code, _, err = run(capsys, "run", cfg, "--out", root / "r", "--spawn")
    assert code == 2 and "--spawn needs --rrd" in err and not (root / "r").exists()


def test_dataset_records_its_encoder_model_and_a_mismatch_is_refused(tmp_path, capsys):
    from selfcal.pipeline.run import run_acquire

    s = load_scenario(overrides={"noise": {"render": False}, "trajectory": {"poses": 6}})
    run_acquire(s, tmp_path / "ds", quiet=True)
    meta = tmp_path / "ds" / "dataset.json"
    doc = json.loads(meta.read_text())
    assert doc["robot_model"] == doc["encoder_model"] == DEFAULT_ROBOT
    doc["robot_model"] = "er4u-vendor"  # other kinematics, but the angles are er4u-paper's
    meta.write_text(json.dumps(doc))
    code, out, err = run(capsys, "calibrate", tmp_path / "ds")
    assert code == 2 and out == ""
    assert err.startswith("selfcal: error: ") and "encoder table of 'er4u-paper'" in err
    assert "robot_model is 'er4u-vendor'" in err and " -- acquire again with" in err


def test_montecarlo_json_and_where_it_wrote(tmp_path, capsys, monkeypatch):
    """The command line's grammar, not the draws: each draw is a row made from its settings (the
    real draws' rows and summaries: tests/integration/test_bounds.py, slow tier, and
    tests/unit/test_seeds_and_checks.py for the command's seeds)."""
    from selfcal.studies.montecarlo import run as montecarlo
    from selfcal.studies.row_checks import check_fields

    row = {"status": "fake", "seconds": 0.0, **check_fields([])}
    monkeypatch.setattr(montecarlo, "draw_one", lambda st: {"seed": st["seed"], **row})
    monkeypatch.chdir(tmp_path)  # --out defaults to runs/montecarlo
    code, out, err = run(
        capsys, "montecarlo", "--draws", "2", "--jobs", "1", "--poses", "8", "--json", "-q"
    )
    assert code == 0
    doc = json.loads(out)
    assert doc == json.loads((tmp_path / "runs/montecarlo/summary.json").read_text())
    last = err.splitlines()[-1]
    assert last.startswith("selfcal: wrote runs/montecarlo/ (") and "summary.json" in last


@pytest.mark.slow  # an acquisition, a calibration and a recording: over 2 s on 2 cores
def test_record_defaults_to_a_file_in_the_dataset(tmp_path, capsys):
    """`selfcal record DIR` without --rrd writes DIR/run.rrd (it used to end in a bare ValueError
    about spawn=True)."""
    from selfcal.pipeline.run import run_acquire, run_calibrate

    s = load_scenario(overrides={"noise": {"render": False}, "trajectory": {"poses": 6}})
    run_acquire(s, tmp_path / "ds", quiet=True)
    run_calibrate(tmp_path / "ds", quiet=True, method="two-stage")
    code, out, err = run(capsys, "record", tmp_path / "ds")
    assert code == 0 and (tmp_path / "ds" / "run.rrd").stat().st_size > 0
    assert err.splitlines()[-1].startswith(f"selfcal: wrote {tmp_path / 'ds' / 'run.rrd'} in ")
