"""One run of a study (``selfcal.studies.study``): a simulated calibration with a few settings changed
(:func:`run_one`), its identity (:func:`settings_key`) and its row in ``runs.csv``
(``COLUMNS``, :func:`load_runs`).

A run is acquire -> calibrate -> report of the default scenario (``scenarios/paper.toml``) in a
temporary folder; its measure is the held-out validation tool-tip error after rigid alignment
(``report.json``), with the nominal model's error of the same run for contrast.
"""

from __future__ import annotations

import csv
import json
import math
import tempfile
import time
import warnings
from pathlib import Path

from selfcal.config.scenario import load_scenario
from selfcal.pipeline.run import run_acquire, run_calibrate, run_report
from selfcal.studies.row_checks import check_fields

__all__ = [
    "SETTING_KEYS",
    "METRIC_KEYS",
    "COLUMNS",
    "settings_key",
    "run_one",
    "failed_row",
    "load_runs",
]

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
    "checks",
    "failed_checks",
)
"""``checks``: ``"passed"`` or ``"failed"``, the reliability checks of the calibration
(:mod:`selfcal.calibration.field.quality`, what ``selfcal calibrate`` reports as FAILED and ``calibration.json``
records as ``status``); empty for a run that did not finish. ``failed_checks``: the failures,
one sentence each, joined by `` | ``."""
COLUMNS = ("study", "key", *SETTING_KEYS, *METRIC_KEYS)


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
            cal = run_calibrate(root, quiet=True, raise_failed=False)
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
            reproj_rms_px=cal.reprojection_rms_px,
            eff_noise_px=cal.reprojection_rms_px / math.sqrt(2),
            frames=cal.dataset.frames,
            frames_used=cal.dataset.frames_used,
            rank=cal.identification.rank,
            # the report's checks: the calibration's and a validation error worse than the
            # nominal model's (cal.failures alone counted such a run as passed)
            **check_fields(rep["failures"]),
        )
    except Exception as exc:  # noqa: BLE001 - a study records failures instead of stopping
        row["status"] = _failure(exc)
    row["seconds"] = round(time.perf_counter() - t0, 3)
    return row


def _failure(exc: BaseException) -> str:
    return f"failed: {type(exc).__name__}: {str(exc)[:200]}"


def failed_row(settings: dict, exc: BaseException) -> dict:
    """The row of a run whose task failed outside :func:`run_one` (e.g. its worker died on every
    try): the settings, ``status = "failed: <error>"`` and no metrics."""
    return {**{k: settings[k] for k in SETTING_KEYS}, "status": _failure(exc), "seconds": None}


def load_runs(path: Path) -> list[dict]:
    """Rows of a ``runs.csv`` (numbers parsed; empty cells -> None)."""
    if not Path(path).is_file():
        return []
    rows = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            out: dict = {}
            for k, v in r.items():
                if k is None:  # cells beyond the header (a row of a newer layout): dropped
                    continue
                if k in ("study", "key", "status") or v is None:
                    out[k] = v
                elif v == "":
                    out[k] = None
                elif k in ("checks", "failed_checks"):
                    out[k] = v
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
