"""The UR5e and the KR 6 R900 (scenarios/ur5e.toml, scenarios/kr6-r900.toml) reach their tool-tip
Cramer-Rao bounds in a Monte Carlo on the analytic path (issue 13's acceptance: within 1.3x in
>= 30 draws); a one-draw smoke test in the default tier."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mc_draws import draw_without_fair_nominal
from scipy.stats import chi2

from selfcal.studies.montecarlo.run import run_montecarlo

UR5E = Path(__file__).resolve().parents[2] / "scenarios" / "ur5e.toml"
KR6 = Path(__file__).resolve().parents[2] / "scenarios" / "kr6-r900.toml"


def test_one_draw_runs_and_is_near_the_bound():
    """10 poses, one noise draw (~3 s): measured ratio 0.78, 0.40 mm against nominal 1.51 mm."""
    rows, summary = run_montecarlo(1, None, poses=10, jobs=1, quiet=True, config=UR5E)
    row = rows[0]
    assert row["status"] == "ok", row["status"]
    # one draw: ratio^2 ~ chi-square(nu) / nu for an efficient estimator (99.9 % interval)
    nu = row["dof_tip"]
    lo, hi = np.sqrt(chi2.ppf([0.0005, 0.9995], nu) / nu)
    assert lo <= summary["joint"]["tool_tip_ratio"] <= hi
    assert row["joint_tip_rms_mm"] < row["nominal_tip_rms_mm"] / 2


@pytest.mark.slow
@pytest.mark.parametrize("path", [UR5E, KR6], ids=lambda p: p.stem)
def test_reaches_the_tool_tip_bound(path):
    """Measured (30 draws, 2 jobs, ~70 s each): ur5e joint ratio 1.008 (95 % CI 0.91 - 1.10),
    two-stage 7.3, bound 0.164 mm, nominal 1.51 mm; kr6-r900 joint ratio 1.012 (0.89 - 1.15),
    two-stage 58 (three draws above 40 mm), bound 0.244 mm, nominal 1.67 mm."""
    rows, summary = run_montecarlo(
        30, None, jobs=2, quiet=True, config=path, task=draw_without_fair_nominal
    )
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) == 30, [r["status"] for r in rows if r["status"] != "ok"]
    ratio = summary["joint"]["tool_tip_ratio"]
    nu = float(np.median([r["dof_tip"] for r in ok]))
    lo = np.sqrt(chi2.ppf(0.0005, 30 * nu) / (30 * nu))
    assert lo <= ratio <= 1.3
    assert summary["two_stage"]["tool_tip_ratio"] > ratio
