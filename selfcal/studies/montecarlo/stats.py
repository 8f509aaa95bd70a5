"""The statistics of the Monte Carlo (:mod:`selfcal.studies.montecarlo.run`): achieved error / bound.

- tool tip: ``ratio = sqrt(mean_draws rms^2) / bound`` (an unbiased efficient estimator has 1);
- parameters: per parameter ``sqrt(mean_draws err^2) / bound``, then the median over the
  estimated parameters; every free camera parameter of the one-step method likewise
  (``camera_ratios``, against the median bound);
- 95 % intervals: bootstrap over draws (percentile), and for the tool tip also the interval an
  efficient estimator would show with this many draws (``rms^2`` is a weighted sum of chi-squares;
  Satterthwaite's effective degrees of freedom).
"""

from __future__ import annotations

import numpy as np

__all__ = ["METHODS", "efficient_ratio_interval", "summarize"]

METHODS = ("joint", "two_stage")


def _boot(values: np.ndarray, stat, n: int = 2000, seed: int = 0) -> tuple[float, float]:
    """95 % percentile bootstrap interval of ``stat`` over the rows of ``values``."""
    rng = np.random.default_rng(seed)
    k = len(values)
    s = np.array([stat(values[rng.integers(0, k, k)]) for _ in range(n)])
    return float(np.percentile(s, 2.5)), float(np.percentile(s, 97.5))


def efficient_ratio_interval(n_draws: int, dof: float, level: float = 0.95) -> tuple[float, float]:
    """Interval of ``sqrt(mean of n_draws values of rms^2) / bound`` for an unbiased efficient
    estimator when ``rms^2 / bound^2 ~ chi2(dof) / dof`` (Satterthwaite): central ``level``."""
    from scipy.stats import chi2  # ~1 s to import (python -X importtime); only this needs it

    nu = n_draws * dof
    a = (1 - level) / 2
    return float(np.sqrt(chi2.ppf(a, nu) / nu)), float(np.sqrt(chi2.ppf(1 - a, nu) / nu))


def summarize(rows: list[dict]) -> dict:
    """Ratios achieved / bound with 95 % intervals for both methods (see the module docstring)."""
    ok = [r for r in rows if r.get("status") == "ok"]
    res: dict = {"draws": len(rows), "ok": len(ok), "failed": len(rows) - len(ok)}
    # draws whose (joint) calibration failed the reliability checks (selfcal.studies.row_checks)
    res["checks_failed"] = sum(r.get("checks") == "failed" for r in rows)
    res["checks_run"] = sum("checks" in r for r in rows)  # the board route runs none
    if not ok:
        return res
    bound = float(np.median([r["bound_tip_rms_mm"] for r in ok]))
    names = [c[len("held_") :] for c in ok[0] if c.startswith("held_")]
    est = [n for n in names if ok[0][f"bound_{n}"] is not None and not ok[0][f"held_{n}"]]
    pb = np.array([[r[f"bound_{n}"] for n in est] for r in ok], dtype=float)
    pbound = np.median(pb, axis=0)
    res["tool_tip_bound_mm"] = bound
    res["nominal_tip_rms_mm"] = float(np.median([r["nominal_tip_rms_mm"] for r in ok]))
    res["bound_spread"] = float(np.ptp([r["bound_tip_rms_mm"] for r in ok]) / bound)
    dof = [r["dof_tip"] for r in ok if r.get("dof_tip") is not None]
    res["tool_tip_dof"] = float(np.median(dof)) if dof else None
    res["efficient_tip_ratio_ci95"] = (
        efficient_ratio_interval(len(ok), res["tool_tip_dof"]) if dof else None
    )
    for m in METHODS:
        tip2 = np.array([r[f"{m}_tip_rms_mm"] ** 2 for r in ok])
        ratio = float(np.sqrt(tip2.mean()) / bound)
        ci = _boot(tip2[:, None], lambda v: np.sqrt(v.mean()) / bound)
        E = np.array([[r[f"{m}_err_{n}"] for n in est] for r in ok], dtype=float)

        def med_ratio(e, pbound=pbound):
            return float(np.median(np.sqrt(np.mean(e**2, axis=0)) / pbound))

        per = np.sqrt(np.mean(E**2, axis=0)) / pbound
        bias = np.abs(E.mean(axis=0)) / (pbound / np.sqrt(len(ok)))
        res[m] = {
            "tool_tip_rms_mm": float(np.sqrt(tip2.mean())),
            "tool_tip_ratio": ratio,
            "tool_tip_ratio_ci95": ci,
            "param_ratio_median": med_ratio(E),
            "param_ratio_median_ci95": _boot(E, med_ratio),
            "param_ratios": {n: float(v) for n, v in zip(est, per)},
            "param_bias_z": {n: float(v) for n, v in zip(est, bias)},
            "fx_ratio": float(
                np.sqrt(np.mean([r[f"{m}_fx_err_px"] ** 2 for r in ok]))
                / np.median([r["bound_fx_px"] for r in ok])
            ),
        }
    # every free camera parameter of the one-step method: error RMS / median bound
    cams = [c[len("bound_cam_") :] for c in ok[0] if c.startswith("bound_cam_")]
    res["camera_ratios"] = {
        n: float(
            np.sqrt(np.mean([r[f"joint_cam_err_{n}"] ** 2 for r in ok]))
            / np.median([r[f"bound_cam_{n}"] for r in ok])
        )
        for n in cams
    }
    # interval an efficient estimator would give with this many draws (per-parameter: chi2(1))
    res["efficient_param_ratio_ci95_single"] = efficient_ratio_interval(len(ok), 1.0)
    return res
