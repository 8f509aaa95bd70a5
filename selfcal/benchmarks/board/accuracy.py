"""Benchmark: does the predicted tool-point accuracy of a board calibration hold? (issue #29)

Monte Carlo on the analytic board scenario (``scenarios/mono-charuco.toml``: one wrist camera
with a Brown-Conrady lens, a ChArUco board on the table where the home posture looks) for each
robot of :data:`ROBOTS` (the scenario's ``[robot] model`` replaced), every minimal parameter
perturbed: per robot, model and pixel noise level ``--draws`` draws (default :data:`DRAWS`,
rendered :data:`DRAWS_RENDERED`), each its own truth
(perturbation, postures and noise seeded by the draw), 30 calibration postures (``--poses``:
fewer make the selection hold directions, whose deviation the prediction then carries,
:mod:`selfcal.calibration.board.held_prior`), the board route
as ``selfcal run`` calibrates them (:func:`selfcal.pipeline.run.run_acquire`, then
:func:`selfcal.pipeline.board_run.calibrate_board_run`: camera stage, fair nominal, parameter
selection, bounds) and its predicted accuracy (:mod:`selfcal.calibration.board.accuracy`). The
predicted 95 % bound and RMS of the flange's position and orientation are compared with the true
error (the calibrated chain's flange against the true chain's, both in the board frame, no noise)
at the workspace sample's joint vectors (inside the calibrated region, at its edge, over the
joint limits: :mod:`selfcal.kinematics.tool_error`).

Models: ``fits`` (the true robot is a chain of the model's kind), ``compliance`` (the
simulated arm's joint 2 bends by 0.05 deg x cos(q2 + q3) while its encoder reads the commanded
angle, :data:`selfcal.sim.compliance.SHOULDER`, the tracker benchmark's misfit: no constant chain
expresses it; the true flange is then the true chain's at the bent joints) and ``gear`` (one
joint, drawn per truth, turns ``A sin(theta + phase)`` past its reading, ``A`` moving the tool
about 0.2 mm: :func:`selfcal.sim.gear.draw_gear`, which no link table expresses).

Reported per row: coverage (the share of (draw, point) pairs whose true error is within the
predicted 95 % bound; target 90-98 %) beside the central 90 % range of the coverage a right
prediction would show on the same draws (each draw's errors drawn from its own prediction:
:func:`selfcal.benchmarks.tracker.accuracy.coverage_if_right`; one calibration's errors over the
workspace are one draw of its parameters' error, so the pooled coverage of a row's draws
spreads by several per cent, most where few parameter directions move the tool, as the ER-4u's
orientation), the same for the covariance alone (no model error), the
pooled ratio of the predicted to the true RMS (target 0.7-1.4) with the 10-90 % range of the
per-draw ratios, the orientation's coverage with and without the model error, and the share of
draws that counted a model error.

``--render``: the draws' images rendered with MuJoCo and detected by the board route's
detector, as ``selfcal run`` with ``[noise] render = true`` does (``MUJOCO_GL=egl``), at the
image noise levels :data:`IMAGE_SIGMA` (grey levels, ``image_sigma``; ``--noise-px`` sets them);
each row also gives the detector's corner noise, the detected corners against their true
projections (:mod:`selfcal.benchmarks.corner_noise`), and goes to its own block. ``--rows-out FILE`` appends
each finished row to ``FILE``, with the code that measured it (its commit) and its seeds; a row
already in ``FILE`` from the same clean commit, seeds, read-back and draws is kept, not measured
again (:func:`done_rows`: an interrupted run started again goes on where it stopped); ``--from-rows FILE ..``
tables them (a run split into pieces; a later file's rows replace an earlier one's in their
place, :func:`merged_rows`), and the table names the code that measured which rows.

``--real``: the repository's real sets with a board (tests/data/real, docs/real-data.md):
each imported and calibrated as its README says, and the held-out images' reprojection RMS that
the calibration predicts (:func:`selfcal.calibration.board.accuracy.predicted_reprojection`:
the estimate's errors with the share of the held parameters' deviation its folds showed
(:mod:`selfcal.calibration.board.held_prior`), the model error, the joint and pixel noise)
against the one ``selfcal evaluate`` measures (target 0.67-1.5x).

Run: ``uv run python -m selfcal.benchmarks.board.accuracy [--draws 90] [--jobs 2] [--robots
R,..] [--models M,..] [--noise-px S,..] [--poses 30] [--first-seed 1] [--read-back rounded]
[--render] [--rows-out FILE] [--from-rows FILE ..] [--real] [--write-docs]`` (rewrites the tables in docs/tool-accuracy.md:
the analytic draws seeded 1, 2, ... and 181, 182, ..., ``--first-seed 181``, have a block each,
:data:`selfcal.benchmarks.board.accuracy_tables.BLOCK_SEEDS`, and so have the ``gear`` rows,
``--models gear`` alone, :data:`selfcal.benchmarks.board.accuracy_tables.BLOCK_GEAR`; an option no block takes is refused
in one line before anything runs).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
import warnings
from contextlib import redirect_stderr, redirect_stdout
from io import StringIO
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import (
    DEFAULT_MODELS,
    MODELS,
    POSES,
    REGIONS,
    ROBOTS,
    GaussianReadBack,
    draw,
    prior,
    scenario,
    simulated,
    simulated_calibration,
)
from selfcal.benchmarks.board.accuracy_tables import (
    BLOCK_REAL,
    DOC,
    docs_block,
    pooled_rows,
    real_table,
    table,
    table_rendered,
)
from selfcal.benchmarks.doc_blocks import ROOT, code_version, print_table, write_block
from selfcal.benchmarks.pool import map_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.accuracy import (
    board_error_model_from_json,
    predicted_reprojection,
)
from selfcal.calibration.board.dataset import (
    calibrate_board_dataset_detailed,
    dataset_board,
    detect_board,
)
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.evaluate import evaluate_board
from selfcal.calibration.board.held_prior import with_deviation
from selfcal.errors import InputError, InternalError
from selfcal.estimation.joint_report import encoder_sigma
from selfcal.io.atomic import write_text_atomic
from selfcal.io.dataset import Dataset
from selfcal.robot.definition import load_robot
from selfcal.threads import limit_threads

__all__ = [
    "GaussianReadBack",
    "draw",
    "done_rows",
    "draws_per_row",
    "main",
    "merged_rows",
    "prior",
    "real_set",
    "rows_block",
    "run",
    "scenario",
    "simulated",
    "simulated_calibration",
    "table",
    "real_table",
    "DRAWS",
    "DRAWS_RENDERED",
    "MODELS",
    "NOISE_PX",
    "REAL_SETS",
    "ROBOTS",
]

NOISE_PX = (0.05, 0.2, 0.5)
IMAGE_SIGMA = (2.0, 8.0, 16.0)
"""``--render``'s image noise levels (grey levels): the scenarios' default and a noisy sensor."""
DRAWS = 90
"""Draws per row on the analytic path: one calibration's errors over a region are one draw of its
parameters' error, so 30 draws left the ER-4u's pooled coverage at the far end of a right
bound's spread on one seed block and not on the next, and seeds 1-60 are such a block for its
orientation (docs/tool-accuracy.md); every row the same draws, none chosen; the docs block's
count."""
DRAWS_RENDERED = 30
"""Draws per row on the rendered path (``--render``; every image rendered and detected)."""
REAL = ROOT / "tests" / "data" / "real"
REAL_SETS = {
    "nachi-2025-01-17-photoneo": ("nachi_mz25.urdf",
                                  "handeye_data/2025-01-17_data_photoneo/group[1-5]/*.png",
                                  "handeye_data/2025-01-17_data_photoneo/group6/*.png"),
    "nachi-2025-02-05-mecheye": ("nachi_mz25.urdf",
                                 "handeye_data/2025-02-05_data_mecheye/group[1-5]/*.png",
                                 "handeye_data/2025-02-05_data_mecheye/group6/*.png"),
    "ical-charuco": ("virtual_inverse_pose_chain_xyz.urdf", "inputs/images_calib/*.png",
                     "inputs/images_heldout/*.png"),
}  # fmt: skip
"""Per set: the robot file in its inputs/, the calibration and the held-out images (its README)."""


def draws_per_row(draws: int | None, render: bool) -> int:
    """The draws per row: ``draws`` when given (positive), else :data:`DRAWS` on the analytic
    path and :data:`DRAWS_RENDERED` with ``render``.

    Raises:
        InputError: ``draws`` is not positive (``--draws``).
    """
    if draws is None:
        return DRAWS_RENDERED if render else DRAWS
    if draws < 1:
        raise InputError(f"--draws {draws}: give at least 1 draw per row")
    return int(draws)


def run(draws: int = DRAWS, robots=ROBOTS, models=DEFAULT_MODELS, noise_px=NOISE_PX,
        jobs: int = 2, poses: int = POSES, *, render: bool = False,
        rows_file: Path | None = None, first_seed: int = 1,
        read_back: str = "rounded") -> list[dict]:  # fmt: skip
    """One row per (robot, model, noise, region) over ``draws`` draws (``jobs`` processes) of
    ``poses`` calibration postures each, seeded ``first_seed``, ``first_seed + 1``, ... (every
    row the same seeds); ``render``: ``noise_px`` are the rendered images' sensor noise levels
    (grey levels); ``rows_file``: each finished row appended (JSON lines); ``read_back``: the
    simulated joint read-back (:func:`draw`). Each row's ``code`` is the code that measured it
    (:func:`selfcal.benchmarks.doc_blocks.code_version`), which the table names."""
    rows = []
    code = code_version()
    stamp = {"code": code, "first_seed": first_seed, "read_back": read_back}
    for robot in robots:
        for model in models:
            for s in noise_px:
                kept = done_rows(rows_file, stamp | {"robot": robot, "model": model,
                                                     "noise_px": s, "poses": poses},
                                 draws, render)  # fmt: skip
                if kept:  # the file's rows of this code and these seeds: not measured again
                    print(f"{robot} {model} {s} px: kept from {rows_file} (the code at {code}, "
                          f"seeds {first_seed}-{first_seed + draws - 1})", file=sys.stderr,
                          flush=True)  # fmt: skip
                    rows += kept
                    continue
                t0 = time.perf_counter()
                args = [(robot, 0.0 if render else s, model, seed, poses, s if render else None,
                         read_back) for seed in range(first_seed, first_seed + draws)]  # fmt: skip
                got = map_jobs(draw, args, jobs)
                fails = sorted({g["status"] for g in got} - {"ok"})
                print(f"{robot} {model} {s} px: {sum(g['status'] == 'ok' for g in got)}/{draws} "
                      f"draws in {time.perf_counter() - t0:.0f} s " + "; ".join(fails),
                      file=sys.stderr, flush=True)  # fmt: skip
                rows += [r | stamp for r in pooled_rows(robot, model, s, got, poses)]
                shown = table_rendered if render else table
                print(shown(rows[-len(REGIONS) :]).split("\n\n")[0], file=sys.stderr, flush=True)
                if rows_file is not None:  # appended: the file's rows and the new ones
                    old = rows_file.read_text() if rows_file.exists() else ""
                    new = "".join(json.dumps(r) + "\n" for r in rows[-len(REGIONS) :])
                    write_text_atomic(rows_file, old + new)
    return rows


def done_rows(rows_file: Path | None, key: dict, draws: int, render: bool) -> list[dict]:
    """The rows (one per region) of ``rows_file`` (``--rows-out``, JSON lines) that this run
    would measure again, to be kept instead: the same ``key`` (robot, model, ``noise_px``,
    ``poses``, ``code``, ``first_seed``, ``read_back``; a row without ``first_seed`` /
    ``read_back`` was measured with 1 / ``"rounded"``), ``draws`` draws (failed ones included)
    and path (``render``: rendered rows have the detector's corner noise); [] when the file or
    one region's row is missing, or the code is not a clean commit (None or ``+changes``: the
    same name need not be the same code), so an interrupted run goes on where it stopped.

    Raises:
        InputError: a line of the file is not a row (:func:`merged_rows`).
    """
    code = key.get("code")
    if rows_file is None or not rows_file.exists() or not code or code.endswith("+changes"):
        return []
    old = {"first_seed": 1, "read_back": "rounded"}

    def same(r: dict) -> bool:
        return (all((old | r).get(k) == v for k, v in key.items())
                and r["draws"] + r["failed"] == draws and ("corner_sigma_px" in r) == render)  # fmt: skip

    found = {r["region"]: r for r in merged_rows([rows_file]) if same(r)}
    return [found[g] for g in REGIONS] if all(g in found for g in REGIONS) else []


def _selfcal(*argv: str) -> None:
    from selfcal.cli.main import main as selfcal

    with redirect_stdout(StringIO()), redirect_stderr(StringIO()):
        code = selfcal(list(argv))
    if code != 0:
        raise InternalError(f"the benchmark's `selfcal {' '.join(argv)}` exited {code}")


IMPORTED = ("dataset.json", "joints.csv", "sources.csv", "frames", "robot")
"""What ``selfcal import`` writes into a dataset folder (and all :func:`real_set` reads)."""


def real_set(name: str, work: Path, imported: tuple[Path, Path] | None = None) -> dict:
    """The predicted against the measured held-out reprojection RMS (px) of the real set
    ``name`` (:data:`REAL_SETS`) calibrated in ``work``.

    ``imported``: the set's calibration and held-out splits as ``selfcal import`` wrote them
    with this set's files (robot, images, joints in rad, target: the tests/real tier imports
    them so already), whose import's files (:data:`IMPORTED`) are copied into ``work`` instead
    of importing the images again; anything else in those folders (a calibration) is ignored.
    """
    robot_file, cal_glob, held_glob = REAL_SETS[name]
    d = REAL / name
    inp = d / "inputs"
    given = imported or (None, None)
    for out, glob, joints, src in (("cal", cal_glob, "joints_calib.csv", given[0]),
                                   ("held", held_glob, "joints_heldout.csv", given[1])):  # fmt: skip
        if src is not None:
            _copy_import(Path(src), work / out)
            continue
        _selfcal("import", "--robot", str(inp / robot_file), "--images", f"cam0={d / glob}",
                 "--joints", str(inp / joints), "--joint-units", "rad", "--target",
                 str(inp / "target.toml"), "--out", str(work / out))  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        det = calibrate_board_dataset_detailed(work / "cal")
        cal = det.result
        ev = evaluate_board(cal, str(work / "cal" / "calibration.json"), work / "held")
        held = Dataset.open(work / "held")
        board = dataset_board(held)
        feats, _ = detect_board(held, board, held.info.cameras[0])
    assert det.cramer_rao is not None and cal.accuracy is not None
    keep = [i for i, f in enumerate(feats) if len(f) >= board.min_features]
    q = np.radians(held.joints_deg)[keep]
    me = cal.accuracy.get("model_error") or {}
    robot = load_robot(Dataset.open(work / "cal").robot_source)
    js = encoder_sigma(robot)
    args: dict[str, Any] = dict(eye_to_hand=cal.eye_to_hand, joint_sigma=js,
                T_tool_point=np.asarray(cal.accuracy["T_tool_point_si"]))  # fmt: skip
    pts = [board.points(feats[i].ids) for i in keep]
    hd = cal.accuracy.get("held_deviation") or {}
    dev = Deviation(hd.get("translation_mm", 0.0) / 1e3, np.radians(hd.get("rotation_deg", 0.0)))
    cr = with_deviation(det.cramer_rao,
                        hd.get("share", 1.0) * dev.variance(cal.model.joint_types))  # fmt: skip
    em = board_error_model_from_json(cal.accuracy, cal.model, "calibration.json")
    pred = predicted_reprojection(cr, cal.cameras[0], q, pts,
                                  model_error_m=(me.get("position_mm") or 0.0) / 1e3,
                                  model_error_rad=np.radians(me.get("rotation_deg") or 0.0),
                                  reach=em.reach, **args)  # fmt: skip
    cov_only = predicted_reprojection(det.cramer_rao, cal.cameras[0], q, pts, model_error_m=0.0,
                                      model_error_rad=0.0, **args)  # fmt: skip
    cv = cal.accuracy.get("cross_validation") or {}
    return {
        "set": name,
        "images": len(keep),
        "measured_px": ev.rms["calibrated"],
        "nominal_px": ev.rms["nominal"],
        "predicted_px": pred,
        "covariance_px": cov_only,
        "model_error_mm": me.get("position_mm"),
        "cv_px": (cv.get("calibrated") or {}).get("reprojection_rms_px"),
        "cv_nominal_px": (cv.get("nominal") or {}).get("reprojection_rms_px"),
    }


def _copy_import(src: Path, dst: Path) -> None:
    """The files ``selfcal import`` wrote in ``src`` (:data:`IMPORTED`) copied to ``dst``.

    Raises:
        InputError: ``src`` lacks one of them (not an imported dataset folder).
    """
    missing = [n for n in IMPORTED if not (src / n).exists()]
    if missing:
        raise InputError(f"{src}: no {', '.join(missing)}: not a folder `selfcal import` wrote; "
                         "import the set there first, or leave `imported` out")  # fmt: skip
    dst.mkdir(parents=True)
    for n in IMPORTED:
        if (src / n).is_dir():
            shutil.copytree(src / n, dst / n)
        else:
            shutil.copy2(src / n, dst / n)


def merged_rows(files: list[Path]) -> list[dict]:
    """The rows of the ``--rows-out`` files ``files`` (JSON lines) in order, a later file's row
    replacing an earlier one's of the same robot, model, noise level and region in its place
    (a block made of a whole run and a rerun of some of its rows; each row keeps its ``code``).

    Raises:
        InputError: a line is not a JSON row (the file and line named).
    """
    rows: dict[tuple, dict] = {}
    for path in files:
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                r = json.loads(line)
                key = (r["robot"], r["model"], r["noise_px"], r["region"])
            except (json.JSONDecodeError, KeyError, TypeError) as exc:
                raise InputError(f"{path}: line {n} is not a row of --rows-out ({exc})",
                                 fix="give files that --rows-out wrote") from exc  # fmt: skip
            rows[key] = r
    return list(rows.values())


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, help=f"draws per row (default {DRAWS}, rendered "
                    f"{DRAWS_RENDERED})")  # fmt: skip
    ap.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    for flag, default in (("--robots", ROBOTS), ("--models", DEFAULT_MODELS)):
        ap.add_argument(flag, type=lambda t: tuple(t.split(",")), default=default,
                        help=f"comma-separated (default {','.join(default)})")  # fmt: skip
    ap.add_argument("--read-back", choices=("rounded", "gaussian"), default="rounded",
                    help="the simulated joint read-back: the motor counts rounded (default) or a "
                    "Gaussian error of the same standard deviation")  # fmt: skip
    ap.add_argument("--first-seed", type=int, default=1,
                    help="the first draw's seed (default 1; other seeds: other draws)")  # fmt: skip
    ap.add_argument("--poses", type=int, default=POSES,
                    help=f"calibration postures per draw (default {POSES})")  # fmt: skip
    ap.add_argument("--noise-px", type=lambda t: tuple(float(x) for x in t.split(",")),
                    default=NOISE_PX, help="comma-separated corner noise levels (px; default "
                    f"{','.join(map(str, NOISE_PX))})")  # fmt: skip
    for flag, text in (("--real", "the real sets' held-out images instead of the Monte Carlo"),
                       ("--render", "render and detect the images (MUJOCO_GL=egl); --noise-px "
                        f"are then the image noise levels (grey levels, default "
                        f"{','.join(map(str, IMAGE_SIGMA))})"),
                       ("--write-docs", "rewrite the table in docs/tool-accuracy.md")):  # fmt: skip
        ap.add_argument(flag, action="store_true", help=text)
    ap.add_argument("--rows-out", type=Path, help="append each finished row here (JSON lines)")
    ap.add_argument("--from-rows", type=Path, nargs="+", metavar="FILE",
                    help="table the rows of earlier --rows-out files instead of running (a later "
                    "file's row replaces an earlier one's of the same robot, model, noise and "
                    "region in its place)")  # fmt: skip
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread per process) and print, or write, the table; an
    option the blocks do not take, or a bad ``--from-rows`` file, is one line on stderr (exit
    2), before anything runs."""
    limit_threads(1)
    args = _arguments(argv)
    try:
        return _main(args)
    except InputError as exc:
        print(f"board_accuracy: error: {exc}", file=sys.stderr)
        return exc.exit_code


def _main(args: argparse.Namespace) -> int:
    """:func:`main` after the options are read.

    Raises:
        InputError: ``--write-docs`` with rows no block holds (:func:`rows_block`), or a
            ``--from-rows`` file that is not rows.
    """
    if args.real:
        rows = []
        for name in REAL_SETS:
            with tempfile.TemporaryDirectory(prefix="selfcal-real-") as d:
                t0 = time.perf_counter()
                rows.append(real_set(name, Path(d)))
                print(f"{name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        text = real_table(rows)
        print(text)
        if args.write_docs:
            write_block(DOC, text, BLOCK_REAL)
        return 0
    block = ""
    if args.from_rows is not None:
        rows = merged_rows(args.from_rows)
        args.render = all("corner_sigma_px" in r for r in rows)
        block = rows_block(rows, args.first_seed, args.from_rows) if args.write_docs else ""
    else:
        if args.write_docs:  # refused before any draw runs
            block = docs_block(args.first_seed, args.read_back, args.poses, args.render,
                               args.models)  # fmt: skip
        noise = IMAGE_SIGMA if args.render and args.noise_px == NOISE_PX else args.noise_px
        draws = draws_per_row(args.draws, args.render)
        rows = run(draws, args.robots, args.models, noise, jobs=args.jobs,
                   poses=args.poses, render=args.render, rows_file=args.rows_out,
                   first_seed=args.first_seed, read_back=args.read_back)  # fmt: skip
    shown = table_rendered(rows) if args.render else table(rows)
    return print_table(shown, DOC, block, write=args.write_docs)


def rows_block(rows: list[dict], first_seed: int, files: list[Path]) -> str:
    """The block ``--write-docs`` writes the rows ``rows`` of the ``--from-rows`` files
    ``files`` into (:func:`docs_block`): all of one first seed, ``first_seed`` (``--first-seed``,
    so that the command names the block it writes), one read-back and :data:`POSES` postures.

    Raises:
        InputError: the rows differ in those, their seed is not ``first_seed``, or no block
            holds them.
    """
    if not rows:
        raise InputError(f"--from-rows {' '.join(map(str, files))}: no rows",
                         fix="give files that --rows-out wrote")  # fmt: skip
    old = {"first_seed": 1, "read_back": "rounded", "poses": POSES}
    kinds = {tuple((old | r)[k] for k in old) for r in rows}
    if len(kinds) != 1:
        raise InputError("--from-rows: the rows mix first seeds, read-backs or postures "
                         f"{sorted(kinds)}: a block holds one of them",
                         fix="give the files of one run, or drop --write-docs")  # fmt: skip
    seed, read_back, poses = kinds.pop()
    if seed != first_seed:
        raise InputError(f"--from-rows: the rows are of the draws seeded {seed}, ... and "
                         f"--first-seed is {first_seed}", fix=f"give --first-seed {seed}")  # fmt: skip
    return docs_block(seed, read_back, poses, all("corner_sigma_px" in r for r in rows),
                      tuple(dict.fromkeys(r["model"] for r in rows)))  # fmt: skip


if __name__ == "__main__":
    sys.exit(main())
