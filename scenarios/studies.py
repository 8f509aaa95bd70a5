"""``selfcal study NAME --budget quick|full --out DIR [--jobs N]``: many calibrations, in parallel.

Each run is one simulated calibration (acquire -> calibrate -> report in a temporary folder) of
the default scenario (``scenarios/paper.toml``) with a few settings changed; its result is one row
of ``DIR/runs.csv``. The measure is the held-out validation tool-tip error after rigid alignment
(``report.json``: RMS over 20 validation postures, mm) of the calibrated model, with the nominal
model's error of the same run for contrast.

Studies (x = the swept setting; seeds vary the perturbation, the trajectory and the noise):

- ``noise``: analytic corner noise ``pixel_sigma`` 0 .. 2 px;
- ``poses``: number of calibration poses 6 .. 100 (analytic, 0.25 px);
- ``perturbation``: size of the injected kinematic errors, a factor on (1 mm, 0.5 deg);
- ``observation``: rendered images (several ``image_sigma``) against analytic projections with the
  SAME effective corner noise: each analytic run uses ``pixel_sigma`` = the paired rendered run's
  reprojection RMS / sqrt(2) (same seed, same postures). Runs in two phases.
- ``all``: the four above, each in ``DIR/<name>/``.

Runs are keyed by their complete settings: an interrupted study (Ctrl-C) keeps every finished row,
and running it again does only the missing runs. Workers are ``spawn``-ed processes with one BLAS
/ OpenMP thread each.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import InputError
from scenarios.config import load_scenario
from scenarios.parallel import worker_pool
from scenarios.pipeline import run_acquire, run_calibrate, run_report
from scenarios.plotting import pyplot

__all__ = ["STUDIES", "Study", "run_one", "run_study", "load_runs", "summarize", "register"]

SETTING_KEYS = ("render", "pixel_sigma", "image_sigma", "poses", "perturb_scale", "seed")
METRIC_KEYS = (
    "status",
    "cal_rms_mm",
    "cal_max_mm",
    "nom_rms_mm",
    "nom_max_mm",
    "fx_err_px",
    "mu_err",
    "reproj_rms_px",
    "eff_noise_px",
    "frames",
    "frames_used",
    "rank",
    "seconds",
)
COLUMNS = ("study", "key", *SETTING_KEYS, *METRIC_KEYS)
BASE = {
    "render": False,
    "pixel_sigma": 0.25,
    "image_sigma": 2.0,
    "poses": 30,
    "perturb_scale": 1.0,
}


# ------------------------------------------------------------------------------------ runs
def settings_key(settings: dict) -> str:
    """The identity of a run: its complete settings as canonical JSON."""
    return json.dumps({k: settings[k] for k in SETTING_KEYS}, sort_keys=True)


def _overrides(st: dict) -> dict:
    seed = int(st["seed"])
    return {
        "noise": {
            "render": bool(st["render"]),
            "pixel_sigma": float(st["pixel_sigma"]),
            "image_sigma": float(st["image_sigma"]),
            "seed": seed,
        },
        "trajectory": {"poses": int(st["poses"]), "seed": seed},
        "perturbation": {
            "seed": seed,
            "translation_mm": 1.0 * float(st["perturb_scale"]),
            "rotation_deg": 0.5 * float(st["perturb_scale"]),
        },
    }


def run_one(settings: dict) -> dict:
    """One calibration with ``settings`` (keys ``SETTING_KEYS``); returns the metrics row.

    Never raises for a failed calibration: the row's ``status`` says ``failed: <reason>``.
    """
    t0 = time.perf_counter()
    row = {k: settings[k] for k in SETTING_KEYS}
    try:
        s = load_scenario(None, _overrides(settings))
        with tempfile.TemporaryDirectory(prefix="selfcal-study-") as d, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            root = Path(d) / "run"
            run_acquire(s, root, quiet=True)
            cal = run_calibrate(root, quiet=True)
            rep = run_report(root, quiet=True)
        v = rep["validation"]["tool_tip_error_mm"]
        row.update(
            status="ok",
            cal_rms_mm=v["calibrated"]["rms"],
            cal_max_mm=v["calibrated"]["max"],
            nom_rms_mm=v["nominal"]["rms"],
            nom_max_mm=v["nominal"]["max"],
            fx_err_px=rep["intrinsics"]["fx"]["estimate"] - rep["intrinsics"]["fx"]["truth"],
            mu_err=rep["intrinsics"]["mu"]["estimate"] - rep["intrinsics"]["mu"]["truth"],
            reproj_rms_px=cal["reprojection_rms_px"],
            eff_noise_px=cal["reprojection_rms_px"] / math.sqrt(2),
            frames=cal["dataset"]["frames"],
            frames_used=cal["dataset"]["frames_used"],
            rank=cal["identification"]["rank"],
        )
    except Exception as exc:  # noqa: BLE001 - a study records failures instead of stopping
        row["status"] = f"failed: {type(exc).__name__}: {str(exc)[:200]}"
    row["seconds"] = round(time.perf_counter() - t0, 3)
    return row


def load_runs(path: Path) -> list[dict]:
    """Rows of a ``runs.csv`` (numbers parsed; empty cells -> None)."""
    if not Path(path).is_file():
        return []
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            out: dict = {}
            for k, v in r.items():
                if k in ("study", "key", "status") or v is None:
                    out[k] = v
                elif v == "":
                    out[k] = None
                elif k == "render":
                    out[k] = v == "True"
                else:
                    try:
                        out[k] = (
                            int(v)
                            if k in ("poses", "seed", "frames", "frames_used", "rank")
                            else float(v)
                        )
                    except ValueError:
                        out[k] = None
            rows.append(out)
    return rows


# --------------------------------------------------------------------------------- studies
@dataclass(frozen=True)
class Study:
    """A named sweep: ``phases(budget, done_rows)`` yields the settings of each phase in turn."""

    name: str
    x: str
    xlabel: str
    phases: tuple[Callable[[str, list[dict]], list[dict]], ...]
    log_x: bool = False
    series: str | None = None  # a settings key that splits the runs into curves


def _seeds(budget: str, quick: int, full: int) -> range:
    return range(1, 1 + (quick if budget == "quick" else full))


def _grid(budget: str, key: str, quick: list, full: list, seeds: tuple[int, int], **fixed):
    vals = quick if budget == "quick" else full
    return [{**BASE, **fixed, key: v, "seed": s} for v in vals for s in _seeds(budget, *seeds)]


def _noise(budget, _rows):
    return _grid(
        budget,
        "pixel_sigma",
        [0.0, 0.5, 2.0],
        [0.0, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0],
        (2, 8),
        poses=12 if budget == "quick" else 30,
    )


def _poses(budget, _rows):
    return _grid(budget, "poses", [8, 40], [6, 8, 12, 20, 30, 50, 70, 100], (3, 8))


def _perturbation(budget, _rows):
    return _grid(
        budget,
        "perturb_scale",
        [0.5, 2.0],
        [0.25, 0.5, 1.0, 2.0, 4.0, 8.0],
        (2, 8),
        poses=12 if budget == "quick" else 30,
    )


def _observation_rendered(budget, _rows):
    return _grid(
        budget,
        "image_sigma",
        [2.0],
        [0.0, 2.0, 8.0],
        (2, 5),
        render=True,
        poses=8 if budget == "quick" else 20,
        pixel_sigma=0.0,
    )


def _observation_analytic(budget, rows):
    out = []
    for st in _observation_rendered(budget, rows):
        match = [r for r in rows if r["key"] == settings_key(st) and r["status"] == "ok"]
        if match:
            eff = round(float(match[0]["eff_noise_px"]), 4)
            # image_sigma records the rendered run it is paired with (unused when not rendering).
            out.append({**st, "render": False, "pixel_sigma": eff})
    return out


STUDIES: dict[str, Study] = {
    "noise": Study("noise", "pixel_sigma", "analytic corner noise sigma (px)", (_noise,)),
    "poses": Study("poses", "poses", "calibration poses", (_poses,), log_x=True),
    "perturbation": Study(
        "perturbation",
        "perturb_scale",
        "injected error size (x 1 mm, x 0.5 deg per parameter)",
        (_perturbation,),
        log_x=True,
    ),
    "observation": Study(
        "observation",
        "image_sigma",
        "rendered image noise sigma (grey levels)",
        (_observation_rendered, _observation_analytic),
        series="render",
    ),
}


# ------------------------------------------------------------------------------------ driver
def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def run_study(
    name: str,
    out: str | Path,
    *,
    budget: str = "quick",
    jobs: int | None = None,
    quiet: bool = False,
) -> list[dict]:
    """Run (or resume) study ``name`` into ``out``; returns all its rows (old and new).

    Writes ``out/runs.csv`` (a row per finished run, flushed at once), ``out/<name>.png`` and
    ``out/<name>.md``. ``jobs`` worker processes (default: the CPU count; 1 runs in-process).

    Raises:
        ValueError: unknown study or budget.
    """
    if name == "all":
        rows = []
        for n in STUDIES:
            rows += run_study(n, Path(out) / n, budget=budget, jobs=jobs, quiet=quiet)
        return rows
    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; choose from {', '.join([*STUDIES, 'all'])}")
    if budget not in ("quick", "full"):
        raise InputError(f"budget must be 'quick' or 'full', got {budget!r}")
    study = STUDIES[name]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / "runs.csv"
    rows = [r for r in load_runs(csv_path) if r.get("study") == name]
    jobs = max(1, int(jobs or os.cpu_count() or 1))
    new_file = not csv_path.is_file()
    fh = open(csv_path, "a", newline="")
    writer = csv.writer(fh)
    if new_file:
        writer.writerow(COLUMNS)
        fh.flush()
    t0 = time.perf_counter()
    try:
        for phase in study.phases:
            done = {r["key"] for r in rows}
            todo = [st for st in phase(budget, rows) if settings_key(st) not in done]
            todo = list({settings_key(st): st for st in todo}.values())
            if not quiet:
                print(
                    f"study {name}: {len(todo)} run(s) to do ({len(done)} done before)",
                    file=sys.stderr,
                )

            def record(row: dict, k: int, n: int) -> None:
                row = {"study": name, "key": settings_key(row), **row}
                writer.writerow([_fmt(row.get(c)) for c in COLUMNS])
                fh.flush()
                rows.append(row)
                if not quiet:
                    msg = (
                        f"cal {row['cal_rms_mm']:.3f} mm, nominal {row['nom_rms_mm']:.3f} mm"
                        if row["status"] == "ok"
                        else row["status"]
                    )
                    print(
                        f"  [{k}/{n}] {row['key']}: {msg} ({row['seconds']:.1f} s)", file=sys.stderr
                    )

            if jobs == 1 or len(todo) <= 1:
                for k, st in enumerate(todo, 1):
                    record(run_one(st), k, len(todo))
            elif todo:
                _run_pool(todo, jobs, record, quiet)
    except KeyboardInterrupt:
        print(
            f"study {name}: interrupted; finished runs are kept in {csv_path}; run the same "
            "command again to resume",
            file=sys.stderr,
        )
        raise
    finally:
        fh.close()
    summarize(name, rows, out)
    if not quiet:
        print(
            f"study {name}: {len(rows)} run(s) in {csv_path}; plot {out / (name + '.png')}; "
            f"{time.perf_counter() - t0:.1f} s",
            file=sys.stderr,
        )
    return rows


def _run_pool(todo: list[dict], jobs: int, record, quiet: bool) -> None:
    with worker_pool(min(jobs, len(todo))) as ex:
        pending: set[Future] = {ex.submit(run_one, st) for st in todo}
        k = 0
        try:
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    k += 1
                    record(f.result(), k, len(todo))
        except KeyboardInterrupt:
            for f in pending:
                f.cancel()
            if not quiet:
                print("interrupted: waiting for the running run(s) to finish ...", file=sys.stderr)
            for f in pending:
                if not f.cancelled():
                    try:
                        row = f.result()
                    except Exception:  # noqa: BLE001
                        continue
                    k += 1
                    record(row, k, len(todo))
            raise


# ---------------------------------------------------------------------------------- outputs
def _stats(v: list[float]) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float)
    return float(np.median(a)), float(np.percentile(a, 25)), float(np.percentile(a, 75))


def summarize(name: str, rows: list[dict], out: str | Path) -> dict:
    """Write ``out/<name>.md`` and ``out/<name>.png`` from the study's rows; returns the table
    ``{series: {x: {n, failed, cal_median, cal_q25, cal_q75, nom_median, x_eff}}}``."""
    study = STUDIES[name]
    out = Path(out)
    table: dict = {}
    for r in rows:
        s = str(r.get(study.series)) if study.series else "all"
        x = r[study.x]
        cell = table.setdefault(s, {}).setdefault(x, {"cal": [], "nom": [], "eff": [], "failed": 0})
        if r["status"] == "ok" and r["cal_rms_mm"] is not None:
            cell["cal"].append(r["cal_rms_mm"])
            cell["nom"].append(r["nom_rms_mm"])
            cell["eff"].append(r["eff_noise_px"])
        else:
            cell["failed"] += 1
    res: dict = {}
    for s, xs in table.items():
        for x, c in sorted(xs.items()):
            if c["cal"]:
                m, q1, q3 = _stats(c["cal"])
                res.setdefault(s, {})[x] = {
                    "n": len(c["cal"]),
                    "failed": c["failed"],
                    "cal_median": m,
                    "cal_q25": q1,
                    "cal_q75": q3,
                    "nom_median": float(np.median(c["nom"])),
                    "eff_noise_median": float(np.median(c["eff"])),
                }
            else:
                res.setdefault(s, {})[x] = {"n": 0, "failed": c["failed"]}
    _write_md(study, res, out / f"{name}.md")
    _plot(study, res, rows, out / f"{name}.png")
    return res


def _series_label(study: Study, s: str) -> str:
    if study.series == "render":
        return "rendered images" if s == "True" else "analytic, same effective noise"
    return "calibrated"


def _write_md(study: Study, res: dict, path: Path) -> None:
    lines = [
        f"# Study `{study.name}`",
        "",
        "Validation tool-tip RMS error (mm, 20 held-out postures, after rigid alignment): median "
        "and inter-quartile range over seeds; the nominal model's median is over the same "
        "(successful) runs. Failed runs are listed in runs.csv with their reason.",
        "",
        f"| series | {study.x} | runs ok | failed | calibrated median | q25 | q75 | nominal median "
        "| effective corner noise (px) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s, xs in res.items():
        for x, c in xs.items():
            if c["n"]:
                lines.append(
                    f"| {_series_label(study, s)} | {x} | {c['n']} | {c['failed']} | "
                    f"{c['cal_median']:.3f} | {c['cal_q25']:.3f} | {c['cal_q75']:.3f} | "
                    f"{c['nom_median']:.3f} | {c['eff_noise_median']:.3f} |"
                )
            else:
                lines.append(f"| {_series_label(study, s)} | {x} | 0 | {c['failed']} | | | | | |")
    path.write_text("\n".join(lines) + "\n")


def _plot(study: Study, res: dict, rows: list[dict], path: Path) -> None:
    plt = pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    colors = {"all": "tab:red", "True": "tab:blue", "False": "tab:orange"}
    offsets = {"True": -0.1, "False": 0.1} if study.series else {"all": 0.0}
    nom_x, nom_y = [], []
    for s, xs in res.items():
        xv = sorted(x for x, c in xs.items() if c["n"])
        if not xv:
            continue
        med = [xs[x]["cal_median"] for x in xv]
        lo = [xs[x]["cal_q25"] for x in xv]
        hi = [xs[x]["cal_q75"] for x in xv]
        xp = np.asarray(xv, dtype=float)
        if study.series:
            xp = xp + offsets.get(s, 0.0) * (np.ptp(xp) if np.ptp(xp) > 0 else 1.0)
        c = colors.get(s, "tab:red")
        ax.plot(xp, med, "o-", color=c, label=f"{_series_label(study, s)} (median)")
        ax.fill_between(xp, lo, hi, color=c, alpha=0.2, label="inter-quartile range")
        pts = [
            (r[study.x], r["cal_rms_mm"])
            for r in rows
            if r["status"] == "ok" and (not study.series or str(r[study.series]) == s)
        ]
        if pts:
            px, py = np.asarray(pts, dtype=float).T
            if study.series:
                px = px + offsets.get(s, 0.0) * (np.ptp(xp) if np.ptp(xp) > 0 else 1.0)
            ax.plot(px, py, ".", color=c, alpha=0.35, ms=4)
        for x, xpk in zip(xv, xp):
            if xs[x]["failed"]:
                ax.annotate(
                    f"{xs[x]['failed']} failed",
                    (xpk, xs[x]["cal_median"]),
                    textcoords="offset points",
                    xytext=(0, -14),
                    ha="center",
                    fontsize=7,
                    color=c,
                )
        nom_x += list(xv)
        nom_y += [xs[x]["nom_median"] for x in xv]
    if nom_x:
        order = np.argsort(nom_x)
        ux, idx = np.unique(np.asarray(nom_x)[order], return_index=True)
        ax.plot(ux, np.asarray(nom_y)[order][idx], "k--", lw=1, label="nominal model (median)")
    ax.set_yscale("log")
    if study.log_x:
        ax.set_xscale("log")
    ax.set_xlabel(study.xlabel)
    ax.set_ylabel("validation tool-tip RMS error (mm)")
    ax.set_title(f"study '{study.name}': error after calibration vs {study.x}")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------------------- CLI
def _cmd(args: argparse.Namespace) -> int:
    run_study(args.name, Path(args.out), budget=args.budget, jobs=args.jobs, quiet=args.quiet)
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal study NAME --budget quick|full --out DIR [--jobs N]``."""
    sp = subparsers.add_parser(
        "study",
        help="run many calibrations (seeds x settings) in parallel: CSV + plots",
        description="Run a study of many simulated calibrations in parallel, resumable: "
        "DIR/runs.csv (one row per run), DIR/NAME.png and DIR/NAME.md. Studies: "
        + ", ".join([*STUDIES, "all"])
        + ". See docs/studies.md.",
    )
    sp.add_argument("name", choices=[*STUDIES, "all"], help="which study")
    sp.add_argument(
        "--budget",
        choices=("quick", "full"),
        default="quick",
        help="quick: a handful of runs (seconds); full: minutes",
    )
    sp.add_argument("--out", required=True, help="output folder (resumes what is there)")
    sp.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="worker processes (default: CPU count; 1 = in-process)",
    )
    sp.add_argument("--quiet", action="store_true")
    sp.set_defaults(func=_cmd)
    return sp
