"""The board accuracy Monte Carlo's rows and Markdown tables (:mod:`selfcal.benchmarks.board.accuracy`,
issue #29): the draws of a row pooled per region, the simulated (analytic and rendered) and the
real sets' tables, and the docs/tool-accuracy.md blocks they go to.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import COUNT, POSES, REGIONS
from selfcal.benchmarks.corner_noise import corner_stats
from selfcal.benchmarks.doc_blocks import ROOT, codes_note
from selfcal.benchmarks.tracker.accuracy import coverage, right_range
from selfcal.benchmarks.tracker.accuracy import mark as _mark
from selfcal.errors import InputError

__all__ = [
    "pooled_rows",
    "table",
    "table_rendered",
    "real_table",
    "BLOCK",
    "BLOCK_REAL",
    "BLOCK_GEAR",
    "BLOCK_RENDER",
    "BLOCK_SEEDS",
    "DOC",
    "docs_block",
]

DOC = ROOT / "docs" / "tool-accuracy.md"
BLOCK = "benchmark_board_accuracy"
BLOCK_REAL = "benchmark_board_accuracy_real"
BLOCK_RENDER = "benchmark_board_accuracy_rendered"
BLOCK_SEEDS = {1: BLOCK, 181: "benchmark_board_accuracy_seeds_181"}
BLOCK_GEAR = "benchmark_board_accuracy_gear"
"""The analytic draws seeded 1, 2, ... of the ``gear`` model (``--models gear`` alone): a block
of their own beside :data:`BLOCK`'s ``fits`` and ``compliance`` rows."""
"""The analytic path's blocks by the draws' first seed (``--first-seed``): the Monte Carlo of
seeds 1, 2, ... and the new draws of seeds 181, 182, ... that check its orientation's
over-coverage (docs/tool-accuracy.md); the rendered path's block is of seeds 1, 2, ...."""


def docs_block(first_seed: int, read_back: str, poses: int, render: bool,
               models: Sequence[str] = ("fits",)) -> str:  # fmt: skip
    """The docs/tool-accuracy.md block that rows of draws seeded ``first_seed``, ... with the
    joint read-back ``read_back``, ``poses`` postures each, ``render`` and the models ``models``
    go to (``--write-docs``; the ``gear`` rows to :data:`BLOCK_GEAR`, alone).

    Raises:
        InputError: no block holds such rows; the message names the option to drop or change.
    """
    blocks = {1: BLOCK_RENDER} if render else BLOCK_SEEDS
    if poses != POSES:
        raise InputError(f"--poses {poses}: --write-docs writes blocks of {POSES} postures",
                         fix="drop --poses, or --write-docs")  # fmt: skip
    if read_back != "rounded":
        raise InputError(f"--read-back {read_back}: --write-docs writes blocks of the rounded "
                         "read-back", fix="drop --read-back, or --write-docs")  # fmt: skip
    if first_seed not in blocks:
        seeds = " or ".join(f"--first-seed {s}" for s in blocks)
        path = "rendered" if render else "analytic"
        raise InputError(f"--first-seed {first_seed}: --write-docs writes the {path} path's "
                         f"blocks of {seeds}", fix=f"give {seeds}, or drop --write-docs")  # fmt: skip
    if "gear" not in models:
        return blocks[first_seed]
    if set(models) != {"gear"} or render or first_seed != 1:
        raise InputError(f"--models {','.join(models)}: --write-docs writes the gear rows, "
                         "analytic and seeded 1, ..., alone into a block of their own",
                         fix="run --models gear alone (no --render, --first-seed), or drop "
                         "--write-docs")  # fmt: skip
    return BLOCK_GEAR


def pooled_rows(robot: str, model: str, s: float, got: list[dict],
                poses: int = POSES) -> list[dict]:  # fmt: skip
    """The rows (one per region) of one robot, model and noise level's draws ``got``."""
    ok = [g for g in got if g["status"] == "ok"]
    rows = []
    for region in REGIONS:
        d = [g[region] for g in ok]
        a = np.concatenate(d, axis=1)
        rows.append({
            "robot": robot, "model": model, "noise_px": s, "region": region, "draws": len(ok),
            "poses": poses,
            "failed": len(got) - len(ok), **coverage(d),
            "true_rot_rms_deg": float(np.sqrt(np.mean(a[6] ** 2))),
            "coverage_rot": float(np.mean(a[6] <= a[4])),
            "coverage_rot_covariance": float(np.mean(a[6] <= a[5])),
            "model_error_share": float(np.mean([g["model_error_mm"] > 0 for g in ok])),
            **_measured(d, [g.get("measured_to") for g in ok]),
            **corner_stats([g["corners"] for g in ok if g.get("corners")]),
            **_right(ok, region),
        })  # fmt: skip
    return rows


def _measured(d: list[np.ndarray], reach: list[float | None]) -> dict:
    """The coverage and the pooled predicted / true RMS apart at the points where the calibration
    measured its model error and where it says it did not (a draw's row 7, 1.0 there:
    :func:`selfcal.benchmarks.board.accuracy_draw.draw`), the share not measured, and the
    median of the draws' reach ``reach`` (the folds' largest held-out distance, unit-free) over
    the draws that have one (finite); none for draws without row 7 (older rows)."""
    if not d or any(len(x) < 8 for x in d):
        return {}
    far = np.concatenate([x[7] for x in d]) > 0.5
    out: dict = {"not_measured_share": float(np.mean(far))}
    for key, pick in (("measured", False), ("not_measured", True)):
        parts = [x[:, (x[7] > 0.5) == pick] for x in d]
        parts = [x for x in parts if x.shape[1]]
        if parts:
            c = coverage(parts)
            out[f"coverage_{key}"], out[f"ratio_{key}"] = c["coverage"], c["ratio"]
    finite = [r for r in reach if r is not None and np.isfinite(r)]
    if finite:
        out["reach_median"] = float(np.median(finite))
    return out


def _right(ok: list[dict], region: str) -> dict:
    """The central 90 % range of the coverage a right prediction would pool over the draws
    ``ok`` in ``region`` (position, orientation; :func:`right_range`); none for draws without
    it."""
    got = [g[f"{region}_right"] for g in ok if f"{region}_right" in g]
    if not got or len(got) < len(ok):
        return {}
    lo, hi = right_range(got)
    return {
        "coverage_right": [float(lo[0]), float(hi[0])],
        "coverage_rot_right": [float(lo[1]), float(hi[1])],
    }


def _range(r: dict, key: str) -> str:
    """A table cell: the row's 90 % range ``key`` (:func:`_right`) in %, or "-"."""
    lo, hi = r.get(key) or (np.nan, np.nan)
    return "-" if not np.isfinite(lo) else f"{100 * lo:.1f}-{100 * hi:.1f} %"


def table(rows: list[dict]) -> str:
    """The Markdown table of :func:`selfcal.benchmarks.board.accuracy.run`'s rows."""
    head = (
        "| robot | model | noise (px) | region | true RMS (mm) | coverage of the 95 % bound "
        "(target 90-98 %) | a right bound's, 90 % range | covariance alone | predicted / true RMS "
        "(target 0.7-1.4) | per draw 10-90 % | true orientation RMS (deg) | orientation coverage "
        "| a right bound's | orientation, covariance alone | draws with a model error | points "
        "where it is not measured | coverage where measured / not measured | predicted / true "
        "RMS where measured / not measured | the folds' reach (median) |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['robot']} | {r['model']} | {r['noise_px']:g} | {r['region']} | "
        f"{r['true_rms_mm']:.3f} | {100 * r['coverage']:.1f} %{_mark(r['coverage'], 0.9, 0.98)} | "
        f"{_range(r, 'coverage_right')} | "
        f"{100 * r['coverage_covariance']:.1f} % | {r['ratio']:.2f}{_mark(r['ratio'], 0.7, 1.4)}"
        f" | {r['ratio_10']:.2f}-{r['ratio_90']:.2f} | {r['true_rot_rms_deg']:.4f} | "
        f"{100 * r['coverage_rot']:.1f} %{_mark(r['coverage_rot'], 0.9, 0.98)} | "
        f"{_range(r, 'coverage_rot_right')} | "
        f"{100 * r['coverage_rot_covariance']:.1f} % | {100 * r['model_error_share']:.0f} % | "
        f"{_split(r)} |"
        for r in rows
    ]
    first = [r for r in rows if r["region"] == REGIONS[0]]
    failed = sum(r["failed"] for r in first)
    poses = "/".join(map(str, sorted({r.get("poses", POSES) for r in first})))
    lines += ["", f"{_sizes(first)} draws per row ({failed} failed in all), "
              f"scenarios/mono-charuco.toml on the analytic path with each robot, {poses} "
              f"calibration postures, {COUNT} joint vectors per region and draw; `uv run python "
              f"-m selfcal.benchmarks.board.accuracy {_options(first)}`"
              f"{_codes(first)}."]  # fmt: skip
    return head + "\n".join(lines)


def _codes(first: list[dict]) -> str:
    """The end of the table's last line: the code that measured the rows ``first`` (one per
    robot, model and noise; their ``code``, :func:`selfcal.benchmarks.board.accuracy.run`),
    :func:`selfcal.benchmarks.doc_blocks.codes_note`."""
    return codes_note(first, ("robot", "model", "noise_px"))


def _split(r: dict) -> str:
    """A row's cells of :func:`_measured`: the share of points not measured, the coverage and
    the predicted / true RMS where measured / not measured (the targets marked where measured;
    "-" where there are no such points), the folds' reach ("-" without any)."""
    if "not_measured_share" not in r:
        return "- | - | - | -"

    def pair(key: str, fmt: str, scale: float, lo: float, hi: float) -> str:
        got = [r.get(f"{key}_{k}") for k in ("measured", "not_measured")]
        unit = " %" if scale == 100 else ""
        cells = ["-" if v is None else f"{scale * v:{fmt}}{unit}" for v in got]
        if got[0] is not None:
            cells[0] += _mark(got[0], lo, hi)
        return " / ".join(cells)

    reach = r.get("reach_median")
    return (f"{100 * r['not_measured_share']:.0f} % | {pair('coverage', '.1f', 100, 0.9, 0.98)} | "
            f"{pair('ratio', '.2f', 1, 0.7, 1.4)} | {'-' if reach is None else f'{reach:.2f}'}")  # fmt: skip


def _sizes(first: list[dict]) -> str:
    """The rows' draws per row (failed ones included), "/"-joined when they differ."""
    return "/".join(map(str, sorted({r["draws"] + r["failed"] for r in first})))


def _options(first: list[dict]) -> str:
    """The benchmark's options that make the rows ``first`` (one per robot, model and noise):
    ``--draws`` (when every row has the same count), ``--robots``, ``--models``, ``--noise-px``
    in the rows' order, ``--first-seed`` / ``--read-back`` when not the defaults, then ``--jobs 1``
    and ``--write-docs`` where a block takes such rows (:data:`BLOCK_SEEDS`)."""
    robots, models, levels = (",".join(dict.fromkeys(f"{r[k]:g}" if k == "noise_px" else r[k]
                                                     for r in first))
                              for k in ("robot", "model", "noise_px"))  # fmt: skip
    draws = _sizes(first)
    count = "" if "/" in draws else f"--draws {draws} "
    seeds = sorted({int(r.get("first_seed", 1)) for r in first})
    backs = sorted({str(r.get("read_back", "rounded")) for r in first})
    other = (f" --first-seed {'/'.join(map(str, seeds))}" if seeds != [1] else "") + \
        (f" --read-back {'/'.join(backs)}" if backs != ["rounded"] else "")  # fmt: skip
    # --write-docs writes the blocks of BLOCK_SEEDS's seeds with the rounded read-back
    block = len(seeds) == 1 and seeds[0] in BLOCK_SEEDS and backs == ["rounded"] and \
        ("gear" not in models.split(",") or (models == "gear" and seeds == [1]))  # fmt: skip
    docs = " --jobs 1 --write-docs" if block else " --jobs 1"
    return f"{count}--robots {robots} --models {models} --noise-px {levels}{other}{docs}"


def table_rendered(rows: list[dict]) -> str:
    """The Markdown table of :func:`selfcal.benchmarks.board.accuracy.run`'s rendered rows (``noise_px`` the image noise)."""
    head = (
        "| robot | model | image noise (grey levels) | detector corner noise (px, median / "
        "largest draw) | its bias / 99 % (px) | region | true RMS (mm) | coverage of the 95 % "
        "bound (target 90-98 %) | a right bound's, 90 % range | covariance alone | predicted / "
        "true RMS (target 0.7-1.4) | per draw 10-90 % | orientation coverage | a right bound's | "
        "draws with a model error |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['robot']} | {r['model']} | {r['noise_px']:g} | {r['corner_sigma_px']:.3f} / "
        f"{r['corner_sigma_max_px']:.3f} | {r['corner_bias_px']:.3f} / {r['corner_p99_px']:.2f} | "
        f"{r['region']} | {r['true_rms_mm']:.3f} | {100 * r['coverage']:.1f} %"
        f"{_mark(r['coverage'], 0.9, 0.98)} | {_range(r, 'coverage_right')} | "
        f"{100 * r['coverage_covariance']:.1f} % | "
        f"{r['ratio']:.2f}{_mark(r['ratio'], 0.7, 1.4)} | {r['ratio_10']:.2f}-{r['ratio_90']:.2f} | "
        f"{100 * r['coverage_rot']:.1f} %{_mark(r['coverage_rot'], 0.9, 0.98)} | "
        f"{_range(r, 'coverage_rot_right')} | {100 * r['model_error_share']:.0f} % |"
        for r in rows
    ]  # fmt: skip
    first = [r for r in rows if r["region"] == REGIONS[0]]
    sizes = _sizes(first)
    lines += ["", f"{sizes} draws per row ({sum(r['failed'] for r in first)} failed in all), "
              "scenarios/mono-charuco.toml rendered with MuJoCo and detected as `selfcal run` "
              "does (`[noise] render = true`, the image noise as `image_sigma`), "
              f"{POSES} calibration postures, {COUNT} joint vectors per region and draw; the "
              "corner noise is the detected corners against their true projections; "
              f"`MUJOCO_GL=egl uv run python -m selfcal.benchmarks.board.accuracy --render "
              f"{_options(first)}`{_codes(first)}."]  # fmt: skip
    return head + "\n".join(lines)


def _real_row(r: dict) -> str:
    k = r["predicted_px"] / r["measured_px"]
    cv = "-" if r["cv_px"] is None else f"{r['cv_px']:.3f} / {r['cv_nominal_px']:.3f}"
    cells = [r["set"], str(r["images"]), f"{r['measured_px']:.3f}", f"{r['predicted_px']:.3f}",
             f"{k:.2f}{_mark(k, 0.67, 1.5)}", f"{r['covariance_px']:.3f}",
             f"{r['model_error_mm'] or 0.0:.3f}", cv]  # fmt: skip
    return "| " + " | ".join(cells) + " |"


def real_table(rows: list[dict]) -> str:
    """The Markdown table of the real sets."""
    cols = ["set", "held-out images", "measured held-out RMS (px)", "predicted (px)",
            "predicted / measured (target 0.67-1.5)", "covariance alone (px)",
            "model error (mm)", "cross-validated calibrated / fair nominal (px)"]  # fmt: skip
    return "\n".join([
        "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols), *map(_real_row, rows), "",
        "the sets' README commands (docs/real-data.md); "
        "`uv run python -m selfcal.benchmarks.board.accuracy --real --write-docs`.",
    ])  # fmt: skip
