"""Rendered Monte Carlo: the default scenario's truth, many image-noise draws, each rendered,
detected and calibrated; the achieved tool-tip error against the reported Cramer-Rao bound.

``python -m selfcal.studies.montecarlo.render --draws 20 --out runs/mc_render [--config FILE]
[--image-sigma 0] [--no-quantize] [--no-dither]``
prints one line per draw and the summary (RMS over draws of the tool-tip RMS, RMS of the
bounds, their ratio). By default each draw also dithers the postures by a uniform fraction of one
encoder count (as ``selfcal/studies/montecarlo/run.py``), so the read-back rounding errors are a fresh draw
with the variance the calibration and the bound assume; ``--no-dither`` keeps the same rounding
errors in every draw (a fixed, truth-like error). Slow (about 15-30 s per draw on 2 cores); see
docs/accuracy.md.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from selfcal.config.scenario import load_scenario
from selfcal.console.usage import module_parser
from selfcal.io.jsonfile import read_report
from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

__all__ = ["run_draws", "summarise"]


def run_draws(
    draws: int,
    out: Path,
    config: str | Path | None = None,
    image_sigma: float | None = None,
    quantize: bool = True,
    dither: bool = True,
) -> list[dict]:
    """``draws`` rendered runs of scenario ``config`` with noise seeds 1..draws into
    ``out/draw_NNN`` (``image_sigma``: grey levels, None: the scenario's; ``quantize``: report
    joints at encoder resolution; ``dither``: move each draw's postures by a random fraction of
    one encoder count); rows ``{seed, rms_mm, bound_mm, max_abs_z, worst, sigma_px,
    sigma_source, residual_sigma_px}`` (``max_abs_z``: the largest |estimate - truth| / std over
    the parameters, ``worst`` its name; ``sigma_px`` the bound's corner noise and where it comes
    from, ``residual_sigma_px`` the final fit's)."""
    rows = []
    for k in range(1, draws + 1):
        noise: dict[str, float | int | bool] = {"seed": k, "quantize_joints": quantize}
        if image_sigma is not None:
            noise["image_sigma"] = image_sigma
        s = load_scenario(config, overrides={"noise": noise})
        d = Path(out) / f"draw_{k:03d}"
        run_acquire(s, d, quiet=True, dither_seed=k if dither else None)
        cal = run_calibrate(d, quiet=True, raise_failed=False)
        run_report(d, quiet=True)
        rep = read_report(d / "report.json")
        z = [
            ((p["estimate"] - p["truth"]) / p["std"], p["name"])
            for p in rep["parameters"]
            if p.get("std") and p.get("truth") is not None
        ]
        zmax = max(z, key=lambda t: abs(t[0]))
        v = rep["validation"]
        b = cal.bounds
        rows.append(
            {
                "seed": k,
                "rms_mm": v["tool_tip_error_mm"]["calibrated"]["rms"],
                "bound_mm": v["tool_tip_bound_mm"],
                "max_abs_z": abs(zmax[0]),
                "worst": zmax[1],
                "sigma_px": None if b is None else b.pixel_sigma_px,
                "sigma_source": None if b is None else b.pixel_sigma_source,
                "residual_sigma_px": rep["effective_corner_noise_px"],
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    return rows


def summarise(rows: list[dict]) -> dict:
    """RMS over the draws of the achieved tool-tip RMS and of the bound (mm), their ratio, and
    the largest parameter |z| of any draw."""
    rms = float(np.sqrt(np.mean([r["rms_mm"] ** 2 for r in rows])))
    bound = float(np.sqrt(np.mean([r["bound_mm"] ** 2 for r in rows])))
    zmax = max(rows, key=lambda r: r["max_abs_z"])
    return {
        "draws": len(rows),
        "rms_mm": rms,
        "bound_mm": bound,
        "ratio": rms / bound,
        "max_abs_z": zmax["max_abs_z"],
        "worst": zmax["worst"],
    }


if __name__ == "__main__":
    ap = module_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--config", default=None)
    ap.add_argument("--image-sigma", type=float, default=None, help="grey levels (0: no noise)")
    ap.add_argument("--no-quantize", action="store_true", help="report the exact joint angles")
    ap.add_argument(
        "--no-dither", action="store_true", help="the same encoder rounding in every draw"
    )
    a = ap.parse_args()
    rows = run_draws(a.draws, a.out, a.config, a.image_sigma, not a.no_quantize, not a.no_dither)
    print(json.dumps(summarise(rows)))
