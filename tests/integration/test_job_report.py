"""The main job's outputs: figures, the parameter table, validation.csv, and `report` without truth.

One analytic dataset (15 postures, 0.5 px corner noise) calibrated and reported with figures; a
copy without truth.json (what every real dataset is) reported from the data alone.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from selfcal.config.scenario import load_scenario
from selfcal.io.calibration import read_calibration
from selfcal.io.dataset import Dataset
from selfcal.pipeline.run import report_summary, run_acquire, run_report
from selfcal.plots.job_figures import parameter_figure, reprojection_figure, tool_tip_figure
from selfcal.plots.plotting import figure_problems

SECTIONS = {"noise": {"render": False}, "trajectory": {"poses": 15}}
OUTPUTS = ("truth.json", "report.json", "report.md", "table_iv.md", "validation.csv", "figures")


@pytest.fixture(scope="module")
def job(default_analytic_15):
    """The default scenario with SECTIONS calibrated and reported with figures, once per test
    run (tests/conftest.py; tests/integration/test_export.py exports the same calibration)."""
    return default_analytic_15


@pytest.fixture(scope="module")
def real(job, tmp_path_factory):
    """The same dataset and calibration as real data: truth.json and the reports removed (the
    calibration never reads truth.json: tests/integration/test_pipeline.py)."""
    out, _ = job
    copy = tmp_path_factory.mktemp("real") / "ds"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns(*OUTPUTS))
    return copy, run_report(copy, quiet=True, figures=True)


def test_report_writes_the_figures_the_table_and_validation_csv(job):
    out, rep = job
    assert rep["figures"] == ["figures/tool_tip_errors.png", "figures/reprojection.png",
                              "figures/parameters.png", "figures/workspace_accuracy.png"]  # fmt: skip
    md = (out / "report.md").read_text()
    for f in rep["figures"]:
        assert (out / f).read_bytes()[:4] == b"\x89PNG" and f"]({f})" in md
    # the parameter table: every minimal parameter with nominal, estimate, sigma, truth, error
    assert len(rep["parameters"]) == 26
    for p in rep["parameters"]:
        assert (
            f"| {p['name']} | {p['unit']} | {p['nominal']:.4f} | {p['estimate']:.4f} | "
            f"{p['std']:.4f} | {p['truth']:.4f} | {p['estimate'] - p['truth']:+.4f} |"
        ) in md
    # validation.csv: one row per validation posture; its norms give the report's RMS
    with open(out / "validation.csv") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == rep["validation"]["poses"] == 20
    tt = rep["validation"]["tool_tip_error_mm"]
    for model in ("nominal", "calibrated"):
        e = np.array([float(r[f"{model}_mm"]) for r in table])
        assert np.sqrt(np.mean(e**2)) == pytest.approx(tt[model]["rms"], abs=1e-5)
        assert e.max() == pytest.approx(tt[model]["max"], abs=1e-5)


def test_calibrate_draws_the_reprojection_figure(job):
    out, _ = job
    assert (out / "figures" / "reprojection.png").is_file()


@pytest.mark.slow  # the field evaluated and 3 figures drawn again: over 2 s on 2 cores; the
# default tier checks the figures' layout on small data (tests/unit/test_figures.py)
def test_every_main_job_figure_has_labelled_axes_and_a_legend_over_no_data(job):
    out, rep = job
    from selfcal.calibration.field.evaluate import evaluate_field

    with open(out / "validation.csv") as fh:
        table = list(csv.DictReader(fh))
    err = {m: np.array([[float(r[f"{m}_e{a}_mm"]) for a in "xyz"] for r in table])
           for m in ("nominal", "calibrated")}  # fmt: skip
    assert figure_problems(tool_tip_figure(err["nominal"], err["calibrated"])) == []
    ev = evaluate_field(read_calibration(out), out, out)
    assert figure_problems(reprojection_figure(ev, "calibration images")) == []
    assert figure_problems(parameter_figure(rep["parameters"])) == []


def test_report_without_truth_reports_fit_held_out_sigmas_and_identifiability(real):
    """A dataset as it comes from a real robot (no truth.json): the report says what the data
    says: the fit, a leave-poses-out check (every 5th of 15 frames, by their joints, held out: 3 frames, 6
    images), the parameters' sigmas and the identifiability."""
    root, rep = real
    cal = read_calibration(root)
    assert rep["kind"] == "fit" and rep["fit"]["reprojection_rms_px"] == cal.reprojection_rms_px
    h = rep["held_out"]
    ds = Dataset.open(root)  # every 5th in the order of the joints, not of the rows
    by_joints = sorted(range(len(ds.indices)), key=lambda k: tuple(ds.joints_deg[k]))
    assert h["source"] == "leave-poses-out"
    assert h["held_out_frames"] == sorted(int(ds.indices[k]) for k in by_joints[::5])
    assert h["images"] == 6
    rms = h["reprojection_rms_px"]
    # measured: 0.80 px held out (0.5 px per coordinate: 0.71 px 2-D) against 11.6 px nominal
    assert rms["calibrated"] < 1.5 and rms["nominal"] > 5 * rms["calibrated"]
    held = {p["name"] for p in rep["parameters"] if p["held"]}
    assert cal.joint is not None and held == set(cal.joint.held)  # the gauge, 6 parameters
    assert len(held) == 6
    assert all(p["std"] > 0 for p in rep["parameters"] if not p["held"])
    idf = rep["identifiability"]["two_stage"]
    assert (idf["rank"], idf["n_params"]) == (cal.identification.rank, 26)
    md = (root / "report.md").read_text()
    assert "Held-out reprojection" in md and "](figures/reprojection.png)" in md
    assert (root / "figures" / "reprojection.png").is_file()
    assert not (root / "truth.json").exists() and not (root / "validation.csv").exists()
    line = report_summary(rep, root)
    assert line.startswith("report (no truth): fit ") and "leave-poses-out" in line
    # the predicted tool-point accuracy without truth too: its line (saying the model error is
    # not measured), its section in report.md and its map
    acc = rep["accuracy"]
    assert f"; {acc['line']}; " in line and acc["line"].endswith(acc["model_error_note"])
    assert "## Predicted tool-point accuracy" in md and acc["line"][1:] in md
    assert "figures/workspace_accuracy.png" in rep["figures"]
    assert (root / "figures" / "workspace_accuracy.png").read_bytes()[:4] == b"\x89PNG"


def test_report_without_truth_uses_selfcal_evaluate_when_it_ran(real, tmp_path):
    """With DIR/evaluation.json (`selfcal evaluate` on a second dataset), that is the held-out
    check; here the second dataset is another trajectory of the same scene."""
    from selfcal.calibration.board.evaluate import write_evaluation
    from selfcal.calibration.field.evaluate import evaluate_field

    root, _ = real
    copy = tmp_path / "ds"
    shutil.copytree(root, copy)
    second = tmp_path / "second"
    s = load_scenario(overrides={**SECTIONS, "trajectory": {"poses": 8, "seed": 5}})
    run_acquire(s, second, quiet=True)
    ev = evaluate_field(read_calibration(copy), copy, second)
    write_evaluation(copy / "evaluation.json", ev)
    rep = run_report(copy, quiet=True)
    h = rep["held_out"]
    assert h["source"] == "selfcal evaluate" and h["images"] == len(ev.images) == 16
    assert h["reprojection_rms_px"] == ev.rms
    assert rep["figures"] == []  # figures only when asked (the commands ask)


@pytest.mark.slow  # over 2 s on 2 cores: the default tier keeps to ~90 s
def test_report_of_real_data_needs_no_simulator(real):
    """The no-truth report's modules run with MuJoCo and the simulator unavailable."""
    root, rep = real
    code = (
        "import sys, json\n"
        "sys.modules['mujoco'] = None; sys.modules['sim'] = None\n"
        "from selfcal.io.calibration import read_calibration\n"
        "from selfcal.pipeline.report_fit import fit_report\n"
        f"r = fit_report({str(root)!r}, read_calibration({str(root)!r}))\n"
        "print(json.dumps(r['held_out']['reprojection_rms_px']))\n"
    )
    env = {**os.environ, "SELFCAL_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=600, check=False)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == pytest.approx(rep["held_out"]["reprojection_rms_px"])
