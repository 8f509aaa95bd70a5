"""``python -m selfcal.benchmarks.plan.field_compare [--robot ur5e] [--render] [--pixel-sigma 0.5]
[--draws 30] [--jobs 1] [--out DIR]``: a field plan of ``selfcal plan --target FIELD.toml``
against random postures, achieved in simulation (docs/plan.md, "A marker field"; issue #30).

The cell of docs/plan.md's field example (the UR5e, or ``--robot``'s arm with the same camera
and field; 60 deg 640 x 480 wrist camera, the 20-marker field of 300 mm where the home posture
looks, its scale 200 mm): the plan of 12 and the first 30
of the same candidate sequence (random postures under the same filters:
:func:`selfcal.calibration.field.plan.plan_field`; the random 12 the command prints beside the
plan are their first 12). Every draw is one simulated truth
(``[perturbation] seed`` = the draw: the arm within 1 mm and 0.5 deg) and one noise draw, on the
analytic path (``--render``: rendered with MuJoCo and detected, as ``selfcal run`` with
``[noise] render = true`` does; the plan and the forecast then for ``--pixel-sigma``'s corner
noise, the images' own noise whatever it is) with dithered read-back, calibrated by the field route
(:func:`selfcal.studies.montecarlo.run.draw_one`); the achieved error is the one-step
calibration's validation tool-tip RMS after the best rigid alignment against the truth, beside
the fair nominal's (the nominal chain with the camera, the hand-eye and the points fitted to the
same pixels). Prints per posture set the forecast
(:func:`selfcal.calibration.field.plan.field_forecast`), the achieved median and 90th
percentile, their ratio, the fair nominal's median, the draws that ran and ended ok and the
frames the calibrations used of those planned, then draw by draw (the same seed draws the same
arm for every set) how often the plan errs less than each other set, with the sign test's p-value
(each draw also in
``DIR/draws.jsonl`` as it ends, stamped with the cell, the set's postures and the code that drew
it (:func:`selfcal.benchmarks.doc_blocks.code_version`), and a journal holding another's draws,
or draws of other code, is refused; the table's last line names the code; ``DIR`` by default ``runs/`` and the cell's docs block; the draws run seed by seed, every set's in turn, and a run
stopped before resumes from that journal: ``--draws`` of a journal's seeds alone prints their
table without drawing; a table short of ``--draws`` draws in a set is printed, not written to
the docs, and exits 1; rendered, the table closes with each set's corner noise the renderer and
the detector make at its postures, measured apart from the draws
(:mod:`selfcal.benchmarks.plan.field_noise`), and the set's forecast at it and at its marker
centres' and shapes' noise (:mod:`selfcal.calibration.field.bounds_split`, issue #30); ``--write-docs`` writes it between docs/plan.md's
``benchmark_plan_field_compare`` markers; another robot's or the rendered path's block
``benchmark_plan_field_compare_ROBOT[-rendered]``).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, code_version, codes_note
from selfcal.io.atomic import write_text_atomic

__all__ = ["cell_stamp", "field_cell", "field_sets", "main"]

FIELD = {"markers": 20, "extent_mm": 300.0, "marker_size_mm": 30.0, "scale_length_mm": 200.0}
"""docs/plan.md's field (the plan's defaults, models/targets/field.toml's scale)."""
DOCS = ROOT / "docs/plan.md"
BLOCK = "benchmark_plan_field_compare"
DEFAULT_OUT = "runs/BLOCK"
"""``--out``'s default, read as ``runs/`` and the cell's docs block (:func:`_block`)."""


def field_cell(
    root: Path, robot_name: str = "ur5e", pixel_sigma_px: float = 0.5, render: bool = False
) -> dict:
    """The benchmark's cell (docs/plan.md's field example; ``robot_name``'s arm): ``robot``, ``camera``, the plan's
    ``setup`` (rendered: with ``clear_views``, no planned view shows a marker partly hidden,
    whose corners the detector may return off; the analytic simulator's corners are not), the read-back noise ``joint_sigma`` (n,) rad, the forecast's ``workspace`` (w, n)
    rad, the replay's marker ``layout`` (its scenario written under ``root``) and the planner's
    keywords ``plan_kw``."""
    from selfcal.calibration.field.joint_refine import encoder_sigma
    from selfcal.calibration.field.plan import FieldPlanSetup, forecast_workspace
    from selfcal.camera import Rig
    from selfcal.cli.plan_field import replay_layout
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.io.camera_file import camera_from_fov
    from selfcal.robot.definition import load_robot

    robot = load_robot(robot_name)
    camera = camera_from_fov(60.0, 640, 480)
    setup = FieldPlanSetup(robot, Rig((camera,), np.eye(4)[None], ("left",)),
                           FIELD["extent_mm"] / 1000, np.zeros((0, 6)), clear_views=render)  # fmt: skip
    js = encoder_sigma(robot)
    # the forecast's markers: the replays' simulated field (the same for every set)
    root.mkdir(parents=True, exist_ok=True)
    first = root / "field-scenario.toml"
    write_text_atomic(first, scenario_text(robot_name, camera, None, 12, field=FIELD))
    layout, _ = replay_layout(first, FIELD["scale_length_mm"] / 1000)
    kw = {"seed": 1, "candidates": 400, "markers": 20, "pixel_sigma_px": pixel_sigma_px,
          "joint_sigma": js}  # fmt: skip
    return {"robot": robot, "camera": camera, "setup": setup, "joint_sigma": js,
            "workspace": forecast_workspace(setup, seed=2), "layout": layout, "plan_kw": kw}  # fmt: skip


def field_sets(
    root: Path,
    count: int = 12,
    random_counts: tuple[int, ...] = (30,),
    robot_name: str = "ur5e",
    pixel_sigma_px: float = 0.5,
    render: bool = False,
) -> dict:
    """``{name: (scenario path, q (m, n) rad, forecast m)}``: the plan of ``count`` and the
    first ``random_counts`` random postures of ``robot_name``'s cell (``render``: the rendered
    cell's, :func:`field_cell`), each written as a replay scenario under ``root``; planned and
    forecast for ``pixel_sigma_px`` of corner noise."""
    from selfcal.calibration.field.plan import field_forecast, plan_field, random_plan
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.io.plan_files import joints_csv

    cell = field_cell(root, robot_name, pixel_sigma_px, render)
    robot, camera, setup, js = cell["robot"], cell["camera"], cell["setup"], cell["joint_sigma"]
    ws, layout, kw = cell["workspace"], cell["layout"], cell["plan_kw"]
    names = [f"plan {count}"] + [f"random {n}" for n in random_counts]
    for name in names:
        (root / name.replace(" ", "-")).mkdir(parents=True, exist_ok=True)
    sets = {names[0]: plan_field(setup, count, layout, ws, **kw).q}
    for name, n in zip(names[1:], random_counts, strict=True):
        sets[name] = random_plan(setup, n, seed=kw["seed"])  # the plan's candidate sequence
    out: dict = {}
    for name, q in sets.items():
        folder = root / name.replace(" ", "-")
        write_text_atomic(folder / "joints.csv", joints_csv(q, robot.edge_unit))
        write_text_atomic(folder / "scenario.toml",
                          scenario_text(robot_name, camera, None, len(q), field=FIELD))  # fmt: skip
        fc = field_forecast(setup, layout, q, ws, pixel_sigma_px=pixel_sigma_px, joint_sigma=js)
        out[name] = (folder / "scenario.toml", q / robot.edge_unit, fc.tool_rms_m)
    return out


def forecasts_at(
    root: Path,
    robot_name: str,
    sets: dict,
    pixel_sigma_px: float,
    split: tuple[float, float] | None = None,
) -> dict:
    """``{name: forecast m}`` of the posture sets ``sets`` (:func:`field_sets`' (path, q deg,
    forecast)) at ``pixel_sigma_px`` px of corner noise, in ``robot_name``'s cell (None: no
    bound); ``split``: the marker centres' and shapes' noise (px), the route weighting for
    ``pixel_sigma_px`` (:func:`selfcal.calibration.field.bounds_split.split_tool_rms`)."""
    from selfcal.calibration.field.bounds import BoundsError
    from selfcal.calibration.field.bounds_setup import predicted_setup
    from selfcal.calibration.field.bounds_split import split_tool_rms
    from selfcal.calibration.field.plan import field_forecast
    from selfcal.transforms import inv_pose

    cell = field_cell(root, robot_name, pixel_sigma_px)
    setup, lay, js, ws = cell["setup"], cell["layout"], cell["joint_sigma"], cell["workspace"]
    unit = cell["robot"].edge_unit
    out: dict = {}
    for name, (_, q, _) in sets.items():
        if split is None:
            out[name] = field_forecast(setup, lay, q * unit, ws, pixel_sigma_px=pixel_sigma_px,
                                       joint_sigma=js).tool_rms_m  # fmt: skip
            continue
        try:
            fs = predicted_setup(setup.model_cam, q * unit, setup.rig, lay.ids, lay.corners_world,
                                 lay.normals_world, lay.scale_ids, lay.scale_length_m,
                                 pixel_sigma_px=pixel_sigma_px, joint_sigma=js)  # fmt: skip
            out[name] = split_tool_rms(fs, ws, inv_pose(setup.robot.T_flange_cam),
                                       centre_sigma_px=split[0], shape_sigma_px=split[1])  # fmt: skip
        except BoundsError:
            out[name] = None
    return out


def noise_lines(root: Path, a, sets: dict, stamps: dict[str, str], rows: list[dict]) -> list[str]:
    """The rendered table's closing lines: each set's corner noise measured apart from its
    draws (the set's own postures: a plan with clear views shows cleaner corners than random
    postures; :func:`selfcal.benchmarks.plan.field_noise.measured_noise`, in the set's folder)
    and its forecast at that noise, and at its marker centres' and shapes' noise
    (:func:`selfcal.calibration.field.bounds_split.split_tool_rms`: most of the rendered
    corners' error moves a marker's corners against each other; issue #30), each against the
    set's achieved median."""
    from selfcal.benchmarks.plan.field_noise import NOISE_SEED, measured_noise
    from selfcal.calibration.field.adjust import OUTLIER_FLOOR_PX

    parts = []
    for name, (path, q, _) in sets.items():
        folder = root / name.replace(" ", "-")
        noise = measured_noise(folder, path, q.tolist(), stamps[name], a.pixel_sigma)
        e = [r["joint_tip_rms_mm"] for r in rows if r["set"] == name and r["status"] == "ok"]
        sigma = float(noise["sigma_px"])
        centre, shape = noise.get("centre_sigma_px"), noise.get("shape_sigma_px")
        split = None if centre is None or shape is None else (float(centre), float(shape))
        figs = []
        for what, sp in (("at it", None), ("at the centres' and shapes'", split)):
            if what != "at it" and sp is None:
                continue
            f = forecasts_at(root, a.robot, {name: sets[name]}, sigma, sp)[name]
            ratio = "-" if f is None or not e else f"{np.median(e) / (f * 1000):.2f}"
            figs.append(f"{what} {'none' if f is None else f'{f * 1000:.3f}'} mm (median / it "
                        f"{ratio})")  # fmt: skip
        parts_of = "not measured" if split is None else f"{split[0]:.3f} and {split[1]:.3f} px"
        parts.append(f"{name} {sigma:.3f} px ({noise['count']} corners, {noise['outliers']} "
                     f"left out), its marker centres' and shapes' {parts_of}; the forecast "
                     f"{'; '.join(figs)}")  # fmt: skip
    return [f"\nthe renderer's and detector's corner noise, measured apart from the draws (each "
            f"set's postures rendered for seed {NOISE_SEED}, corners against the truth, those "
            f"beyond the route's {OUTLIER_FLOOR_PX:g} px floor left out; a marker's centre: its "
            f"four corners' mean error, its shape: the rest, each as the white noise that errs "
            f"as much): {' | '.join(parts)}"]  # fmt: skip


def cell_stamp(robot_name: str, render: bool, pixel_sigma_px: float, joints_deg: np.ndarray) -> str:
    """What a journal row was drawn for: the arm, the path (rendered or analytic), the corner
    noise (px) the draws simulate and a digest of the set's postures (deg), so a resumed run
    never tables another cell's or another plan's draws as its own."""
    q = np.ascontiguousarray(np.round(np.asarray(joints_deg, dtype=float), 9))
    digest = hashlib.sha1(q.tobytes()).hexdigest()[:12]
    path = "rendered" if render else "analytic"
    return f"{robot_name} {path} {pixel_sigma_px:g} px postures {digest}"


def _foreign(done: list[dict], stamps: dict[str, str], journal: Path) -> None:
    """Refuse a journal holding a draw of another cell or posture set (:func:`cell_stamp`).

    Raises:
        InputError: naming the journal, the first such draw and the fix.
    """
    from selfcal.errors import InputError

    other = [r for r in done if r.get("cell") != stamps.get(r["set"])]
    if other:
        r = other[0]
        raise InputError(
            f"{journal}: {len(other)} of its {len(done)} draws were made for another cell or "
            f"posture set (first: set {r['set']!r}, seed {r['seed']}, drawn for "
            f"{r.get('cell') or 'a cell not recorded (an older journal)'}; this run's is "
            f"{stamps.get(r['set'], 'a set it does not draw')})",
            fix="give this cell its own --out (the default names the robot and the path), or "
            "move the journal away to draw again",
        )


def _other_code(done: list[dict], code: str | None, journal: Path) -> None:
    """Refuse a journal holding a draw made by other code than ``code`` (this run's,
    :func:`code_version`; a draw without ``code`` is an older journal's), so one table is never
    drawn by two codes.

    Raises:
        InputError: naming the journal, the first such draw and the fix.
    """
    from selfcal.errors import InputError

    other = [r for r in done if r.get("code") != code]
    if other:
        r = other[0]
        was = (
            f"the code at {r['code']}" if r.get("code") else "code not recorded (an older journal)"
        )
        raise InputError(
            f"{journal}: {len(other)} of its {len(done)} draws were made by other code (first: "
            f"set {r['set']!r}, seed {r['seed']}, by {was}; this run is the code at {code})",
            fix="check out that code to go on with the journal, or give this run its own --out, "
            "or move the journal away to draw again",
        )


def _draw(item: tuple[str, str, list, int, bool, float, str, str | None]) -> dict:
    from selfcal.studies.montecarlo.run import draw_one

    name, config, joints_deg, seed, render, sigma, cell, code = item
    row = draw_one({"config": config, "poses": len(joints_deg), "pixel_sigma": sigma,
                    "seed": seed, "traj_seed": 1, "perturb_seed": seed, "dither": True,
                    "joints_deg": joints_deg, "render": render})  # fmt: skip
    keys = ("joint_tip_rms_mm", "fair_nominal_tip_rms_mm", "nominal_tip_rms_mm", "sigma_hat_px")
    return {"set": name, "seed": seed, "cell": cell, "code": code, "status": str(row["status"]),
            "frames_used": row.get("frames_used"), "frames": row.get("frames"),
            **{k: float(row.get(k) or np.nan) for k in keys}}  # fmt: skip


def _options(argv: list[str] | None):
    """The benchmark's options: :func:`selfcal.benchmarks.plan.compare.arguments`' and the cell's."""
    import argparse

    from selfcal.benchmarks.plan.compare import arguments

    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("--robot", default="ur5e", help="the arm (a model name; default ur5e)")
    ap.add_argument("--render", action="store_true", help="rendered and detected images")
    ap.add_argument("--pixel-sigma", type=float, default=0.5,
                    help="the corner noise the plan and the forecast assume (px; default 0.5)")  # fmt: skip
    a = arguments(argv, __doc__ or "", DEFAULT_OUT, 1, write_docs=True, parents=(ap,),
                  module_file=__file__)  # fmt: skip
    if a.out == DEFAULT_OUT:  # each cell its own journal
        a.out = f"runs/{_block(a.robot, a.render)}"
    return a


def _block(robot_name: str, render: bool) -> str:
    """The docs block (and the default run folder's name) of a cell."""
    if (robot_name, render) == ("ur5e", False):
        return BLOCK
    return f"{BLOCK}_{robot_name}{'-rendered' if render else ''}"


def _frames(run: list[dict]) -> str:
    """The frames used of those planned over the draws ``run`` ("not recorded" for older journals)."""
    if not run or any(r.get("frames") is None for r in run):
        return "not recorded"
    return f"{sum(r['frames_used'] for r in run)} of {sum(r['frames'] for r in run)}"


def _paired(rows: list[dict], names: list[str]) -> list[str]:
    """Lines comparing the plan (``names[0]``) with each other set draw by draw: a draw's seed
    draws the same arm for every set, so the two errors are paired; how many draws the plan errs
    less and the one-sided sign test's p-value of that count under "neither set is better"
    (ties dropped), so a median's lead is read with its evidence."""
    from scipy.stats import binomtest

    err = {(r["set"], r["seed"]): r["joint_tip_rms_mm"] for r in rows if r["status"] == "ok"}
    out = []
    for other in names[1:]:
        seeds = sorted(s for (n, s) in err if n == names[0] and (other, s) in err)
        d = np.array([err[(names[0], s)] - err[(other, s)] for s in seeds])
        wins, n = int(np.sum(d < 0)), int(np.sum(d != 0))
        if n == 0:
            continue
        p = binomtest(wins, n, 0.5, alternative="greater").pvalue
        out.append(f"\n{names[0]} against {other}, draw by draw (the same arm): {names[0]} errs "
                   f"less in {wins} of {n} draws (one-sided sign test p = {p:.2g})")  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    """Draw and print the table."""
    from selfcal.benchmarks.doc_blocks import print_table
    from selfcal.benchmarks.plan.compare import draw_all

    a = _options(argv)
    root = Path(a.out)
    sets = field_sets(root, robot_name=a.robot, pixel_sigma_px=a.pixel_sigma, render=a.render)
    journal = root / "draws.jsonl"  # a run stopped before resumes: its draws are not redone
    done = [json.loads(x) for x in journal.read_text().splitlines()] if journal.exists() else []
    stamps = {name: cell_stamp(a.robot, a.render, a.pixel_sigma, q)
              for name, (_, q, _) in sets.items()}  # fmt: skip
    _foreign(done, stamps, journal)
    code = code_version()
    _other_code(done, code, journal)
    have = {(r["set"], r["seed"]) for r in done}
    items = [(name, str(path), q.tolist(), s, a.render, a.pixel_sigma, stamps[name], code)
             for s in range(1, a.draws + 1)
             for name, (path, q, _) in sets.items() if (name, s) not in have]  # fmt: skip
    rows = [r for r in draw_all(_draw, items, a.jobs, root, done) if r["seed"] <= a.draws]
    lines = ["| postures | draws (ok of run) | frames used (of planned) | forecast (mm) | "
             "achieved median (mm) | 90th percentile | median / forecast | fair nominal "
             "median (mm) |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    short = []
    for name, (_, _, pred) in sets.items():
        run = [r for r in rows if r["set"] == name]
        ok = [r for r in run if r["status"] == "ok"]
        if len(run) < a.draws:
            short.append(f"{name}: {len(run)} of {a.draws} draws")
        e = np.array([r["joint_tip_rms_mm"] for r in ok])
        fair = np.nanmedian([r["fair_nominal_tip_rms_mm"] for r in ok])
        med, p90 = np.median(e), np.percentile(e, 90)
        p = "none" if pred is None else f"{pred * 1000:.3f}"
        ratio = "-" if pred is None else f"{med / (pred * 1000):.2f}"
        lines.append(f"| {name} | {len(ok)} of {len(run)} | {_frames(ok)} | {p} | {med:.3f} | "
                     f"{p90:.3f} | {ratio} | {fair:.3f} |")  # fmt: skip
    lines += _paired(rows, list(sets))
    if a.render:
        lines += noise_lines(root, a, sets, stamps, rows)
    cell = "" if a.robot == "ur5e" else f" --robot {a.robot}"
    cell += " --render" if a.render else ""
    cell += "" if a.pixel_sigma == 0.5 else f" --pixel-sigma {a.pixel_sigma:g}"
    lines.append(f"\n`uv run python -m selfcal.benchmarks.plan.field_compare{cell} --draws "
                 f"{a.draws} --jobs 1 --write-docs` (seeds 1 - {a.draws})"
                 f"{codes_note(rows, ('set',))}")  # fmt: skip
    text = "\n".join(lines)
    if short:
        print(text)
        print(f"NOT every draw run ({'; '.join(short)}): the table is not written to the docs")
        return 1
    return print_table(text, DOCS, _block(a.robot, a.render), write=a.write_docs)


if __name__ == "__main__":
    raise SystemExit(main())
