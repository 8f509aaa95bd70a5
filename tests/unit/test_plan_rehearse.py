"""The plan rehearsal benchmark (selfcal/benchmarks/plan/rehearse.py): the seed it sets in the
plan's scenario, its aggregation over the runs (RMS over the seeds, range, parameters kept) and
the table's cells as plan.json states the prediction and the verdict. One tiny plan with one seed
end to end in the slow tier."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from selfcal.benchmarks.plan.rehearse import aggregate, plan_args, seeded, table
from selfcal.cli.plan_scenario import scenario_text
from selfcal.errors import InternalError
from selfcal.io.camera_file import camera_from_fov


def _plan(beats: bool, rival: float | None, more: dict | None = None) -> dict:
    return {"selection": {"tool_rms_mm": 0.6, "kinematic_parameters": 18,
                          "rival_tool_rms_mm": rival,
                          "rival_kinematic_parameters": None if rival is None else 11},
            "nominal": {"drawn_tool_rms_mm": 1.5, "fair_nominal_tool_rms_mm": 6.0,
                        "clear_margin": 0.7},
            "beats_nominal": beats, "more_postures": more}  # fmt: skip


def test_seeded_sets_the_perturbation_and_the_noise_seed() -> None:
    text = scenario_text("ur5e", camera_from_fov(60.0, 640, 480), np.zeros(6), 12)
    out = seeded(text, 7)
    assert "[perturbation]\nseed = 7\n" in out and "[noise]\nseed = 7\n" in out
    assert out.count("seed = ") == 2 and "seed = 1\n" not in out
    with pytest.raises(InternalError):
        seeded(text.replace("[noise]", "[nois]"), 7)


def test_aggregate_takes_the_rms_over_the_runs_and_leaves_failed_ones_out() -> None:
    rows = [{"plan": "ur5e:12", "seed": 1, "calibrated_mm": 3.0, "drawn_mm": 1.0,
             "fair_mm": 6.0, "kept": 11},
            {"plan": "ur5e:12", "seed": 2, "calibrated_mm": 4.0, "drawn_mm": 1.0,
             "fair_mm": 2.0, "kept": 18},
            {"plan": "ur5e:12", "seed": 3, "calibrated_mm": 0.0, "drawn_mm": 1.0,
             "fair_mm": 2.0, "kept": 18},
            {"plan": "ur5e:12", "seed": 4, "error": "no report"},
            {"plan": "arm7:12", "seed": 1, "error": "no report"}]  # fmt: skip
    s = aggregate(rows)
    assert s["ur5e:12"]["runs"] == 4 and s["ur5e:12"]["failed"] == 1
    np.testing.assert_allclose(s["ur5e:12"]["calibrated_mm"], (np.sqrt(25.0 / 3.0), 0.0, 4.0))
    np.testing.assert_allclose(s["ur5e:12"]["fair_mm"], (np.sqrt(44.0 / 3.0), 2.0, 6.0))
    assert list(s["ur5e:12"]["kept"].items()) == [(18, 2), (11, 1)]  # most common first
    np.testing.assert_allclose(s["ur5e:12"]["ratios"], [3.0, 4.0, 0.0])
    assert s["arm7:12"]["failed"] == 1 and s["arm7:12"]["calibrated_mm"] is None


def test_table_states_the_plans_prediction_and_verdict_and_the_runs() -> None:
    rows = [{"plan": "ur5e:12", "seed": s, "calibrated_mm": c, "drawn_mm": 1.5,
             "fair_mm": 6.0, "kept": 18} for s, c in ((1, 0.3), (2, 0.4))]  # fmt: skip
    plans = {
        "ur5e:12": _plan(True, 1.2),
        "arm7:12": _plan(False, None, {"count": 16, "tool_rms_mm": 0.663}),
    }
    lines = table(plans, rows).splitlines()
    assert len(lines) == 4 and all(line.count("|") == 12 for line in lines)
    ur5e = [c.strip() for c in lines[2].split("|")[1:-1]]
    # the reference is the smaller of the drawn chain and the fair nominal: 1.5 mm
    assert ur5e[:6] == ["ur5e 12", "18: 0.6000 (11: 1.2000)", "beats: 0.40 (smaller set 0.80)",
                        "1.5000", "6.0000", "2"]  # fmt: skip
    assert ur5e[6] == f"{np.sqrt((0.09 + 0.16) / 2):.3f} (0.30 - 0.40)"
    # the drawn chain and the fair nominal the same in both runs: no range
    assert ur5e[7:] == ["1.500", "6.000", "18 x 2", "0.20 - 0.27 (at most 0.7 in 2 of 2)"]
    arm7 = [c.strip() for c in lines[3].split("|")[1:-1]]
    assert arm7[1:3] == ["18: 0.6000", "NOT: 0.40; 16 postures: 0.6630 mm"]
    assert arm7[5:] == ["0", "", "", "", "", ""]  # no runs yet


def test_plan_args_are_the_docs_commands() -> None:
    args = plan_args("arm7:16", Path("out"))
    assert args[0] == "plan" and args[args.index("--count") + 1] == "16"
    assert args[args.index("--robot") + 1].endswith("tests/data/arm7.toml")


@pytest.mark.slow
def test_one_plan_rehearsed_with_one_seed(tmp_path) -> None:
    from selfcal.benchmarks.plan.rehearse import _plan as plan_one
    from selfcal.benchmarks.plan.rehearse import rehearse_row

    doc = plan_one(("arm7:12", str(tmp_path / "plan")))
    row = rehearse_row(("arm7:12", str(tmp_path / "plan"), 1))
    rep = json.loads((tmp_path / "seed1/run/report.json").read_text())
    assert row["drawn_mm"] == rep["validation"]["tool_tip_error_mm"]["nominal"]["rms"]
    # the selection keeps what the plan forecasts (all 22 of arm7's at 12 postures)
    assert row["kept"] in (doc["selection"]["kinematic_parameters"],
                           doc["selection"]["rival_kinematic_parameters"])  # fmt: skip
    # the fair nominal (hand-eye fitted at the camera, off at the flange) is the worse reference
    # on arm7 (this draw: 11.7 against 1.05 mm; 5.5 against 1.37 mm predicted)
    assert row["fair_mm"] > 2.0 * row["drawn_mm"]
