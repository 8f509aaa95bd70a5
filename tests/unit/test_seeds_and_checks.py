"""``--seed`` of ``selfcal montecarlo`` and ``selfcal study`` (issue #16) and the reliability
checks in their rows and summaries (issue #15), through the real parser with tasks that need no
calibration (the row is a function of the settings). The real rows' check fields:
tests/integration/test_row_checks.py."""

from __future__ import annotations

import csv
import json

import pytest

from selfcal.cli.main import main as cli_main
from selfcal.studies import study as studies
from selfcal.studies.montecarlo import run as montecarlo
from selfcal.studies.row_checks import check_fields, count_check_failures
from selfcal.studies.runs import COLUMNS, load_runs

FAILURE = "the calibrated model fits worse than the nominal model (10.26 px against 7.01 px)"


def _mc_row(calls: list, settings: dict) -> dict:
    """A Monte Carlo draw without a calibration; draw seed 6 fails its checks."""
    calls.append(settings)
    s = settings["seed"]
    return {
        "seed": s,
        "pixel_sigma": settings["pixel_sigma"],
        "status": "fake",
        "value": s / 7.0,
        "seconds": 0.0,
        **check_fields([FAILURE] if s == 6 else []),
    }


def test_montecarlo_seed_overrides_every_seed_of_the_truth_and_the_draws(
    tmp_path, monkeypatch, capsys
):
    calls: list[dict] = []
    monkeypatch.setattr(montecarlo, "draw_one", lambda st: _mc_row(calls, st))
    argv = ["montecarlo", "--draws", "3", "--jobs", "1", "--json"]
    assert cli_main([*argv, "--out", str(tmp_path / "a"), "--seed", "5"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [c["seed"] for c in calls] == [5, 6, 7]
    assert {(c["traj_seed"], c["perturb_seed"]) for c in calls} == {(5, 5)}
    assert summary["settings"]["traj_seed"] == 5 and summary["settings"]["perturb_seed"] == 5
    # the check status is in every row (journal and CSV) and counted in the summary
    assert summary["checks_failed"] == 1
    with open(tmp_path / "a" / "runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["checks"] for r in rows] == ["passed", "failed", "passed"]
    assert rows[1]["failed_checks"] == FAILURE
    journal = [
        json.loads(x)["row"] for x in (tmp_path / "a" / "draws.jsonl").read_text().splitlines()
    ]
    assert count_check_failures(journal) == 1
    assert "1 of 3 draws failed them" in (tmp_path / "a" / "summary.md").read_text()
    # reproducible: the same seed elsewhere gives the same settings and rows
    first = [dict(c) for c in calls]
    calls.clear()
    assert cli_main([*argv, "--out", str(tmp_path / "b"), "--seed", "5"]) == 0
    capsys.readouterr()
    assert calls == first
    assert (tmp_path / "a" / "runs.csv").read_text() == (tmp_path / "b" / "runs.csv").read_text()
    # without --seed: the seeds of before (truth 1, draws 1..N)
    calls.clear()
    assert cli_main([*argv, "--out", str(tmp_path / "c")]) == 0
    capsys.readouterr()
    assert [(c["seed"], c["traj_seed"], c["perturb_seed"]) for c in calls] == [
        (1, 1, 1),
        (2, 1, 1),
        (3, 1, 1),
    ]


def _study_row(calls: list, settings: dict) -> dict:
    """A study run without a calibration; seed 5 fails its checks."""
    calls.append(settings)
    s = settings["seed"]
    return {
        **settings,
        "status": "ok",
        "cal_rms_mm": 0.1 * s,
        "nom_rms_mm": 2.0,
        "eff_noise_px": settings["pixel_sigma"],
        "seconds": 0.0,
        **check_fields([FAILURE] if s == 5 else []),
    }


def test_study_seed_shifts_every_settings_seeds_and_rows_record_the_checks(
    tmp_path, monkeypatch, capsys
):
    calls: list[dict] = []
    monkeypatch.setattr(studies, "run_one", lambda st: _study_row(calls, st))
    out = tmp_path / "s"
    argv = ["study", "noise", "--jobs", "1", "--json", "--out", str(out)]
    assert cli_main([*argv, "--seed", "4"]) == 0
    doc = json.loads(capsys.readouterr().out)
    # quick noise study: 3 settings x 2 seeds, now seeds 4 and 5 instead of 1 and 2
    assert sorted({c["seed"] for c in calls}) == [4, 5] and len(calls) == 6
    assert doc["runs"] == 6 and doc["checks_failed"] == 3
    rows = load_runs(out / "runs.csv")
    assert [r["checks"] for r in rows] == ["failed" if r["seed"] == 5 else "passed" for r in rows]
    assert all(r["failed_checks"] == FAILURE for r in rows if r["seed"] == 5)
    md = (out / "noise.md").read_text()
    assert "Reliability checks: 3 of 6 run(s) failed them." in md
    assert md.count("| 1 |\n") == 3  # one failed check per setting, the last column
    # the same command again: nothing to run (the seeds are part of each run's key)
    calls.clear()
    assert cli_main([*argv, "--seed", "4"]) == 0
    capsys.readouterr()
    assert calls == []


def test_a_study_begun_before_the_check_columns_resumes(tmp_path, monkeypatch, capsys):
    """runs.csv written without the check columns gets the new header; old rows keep their
    values with empty check cells, new rows are appended in the new layout."""
    calls: list[dict] = []
    monkeypatch.setattr(studies, "run_one", lambda st: _study_row(calls, st))
    out = tmp_path / "old"
    assert cli_main(["study", "noise", "--jobs", "1", "-q", "--out", str(out)]) == 0
    old_cols = [c for c in COLUMNS if c not in ("checks", "failed_checks")]
    rows = load_runs(out / "runs.csv")
    with open(out / "runs.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(old_cols)
        for r in rows[:4]:  # two runs were not finished yet
            w.writerow(["" if r.get(c) is None else r[c] for c in old_cols])
    calls.clear()
    assert cli_main(["study", "noise", "--jobs", "1", "-q", "--out", str(out)]) == 0
    capsys.readouterr()
    assert len(calls) == 2
    with open(out / "runs.csv", newline="") as fh:
        assert tuple(next(csv.reader(fh))) == COLUMNS
    back = load_runs(out / "runs.csv")
    assert len(back) == 6
    assert [r["checks"] for r in back[:4]] == [None] * 4
    assert all(r["checks"] in ("passed", "failed") for r in back[4:])


@pytest.mark.parametrize("failures", [(), (FAILURE,), (FAILURE, "the cameras are swapped")])
def test_check_fields(failures):
    f = check_fields(failures)
    assert f["checks"] == ("failed" if failures else "passed")
    assert f["failed_checks"] == (" | ".join(failures) or None)
