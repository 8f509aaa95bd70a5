"""``selfcal montecarlo [SCENARIO] --draws N [--out DIR] [--jobs 2 | --cluster ADDRESS] [--plans]``: the command of
:mod:`selfcal.studies.montecarlo.run` (and, with ``--plans``, :mod:`selfcal.studies.montecarlo.plan_comparison`)."""

from __future__ import annotations

import argparse
import json

from selfcal.console.common import add_json, add_scenario_arg, note_written

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = ["register", "SEED_HELP"]

SEED_HELP = (
    "seed of the truth and the draws (default 1), overriding the scenario's [perturbation] and "
    "[trajectory] seeds: the perturbation and the calibration postures take seed S, the noise "
    "draws seeds S, S+1, ..., S+draws-1 ([noise] seed); with --plans the trajectory seeds S, "
    "S+1, S+2. The same S gives the same rows; the marker field ([target] seed) and the "
    "validation postures ([validation] seed) stay the scenario's"
)


def _cmd(args: argparse.Namespace) -> int:
    from selfcal.studies.montecarlo.plan_comparison import plans_markdown, run_plan_comparison
    from selfcal.studies.montecarlo.report import summary_markdown
    from selfcal.studies.montecarlo.run import run_montecarlo

    args.out = args.out or ("runs/montecarlo-plans" if args.plans else "runs/montecarlo")
    seed = 1 if args.seed is None else args.seed
    if args.plans:
        res = run_plan_comparison(
            args.out,
            draws=args.draws,
            jobs=args.jobs,
            quiet=args.quiet,
            cluster=args.cluster,
            seeds=(seed, seed + 1, seed + 2),
        )
        print(json.dumps(res, default=str) if args.json else plans_markdown(res))
        note_written(args, args.out)
        return 0
    _, s = run_montecarlo(
        args.draws,
        args.out,
        poses=args.poses,
        pixel_sigma=args.pixel_sigma,
        traj_seed=seed,
        perturb_seed=seed,
        first_seed=seed,
        dither=not args.no_dither,
        jobs=args.jobs,
        quiet=args.quiet,
        config=args.scenario,
        cluster=args.cluster,
        retries=args.retries,
    )
    print(json.dumps(s) if args.json else summary_markdown(s))
    note_written(args, args.out)
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal montecarlo [SCENARIO] [--draws N] [--out DIR] [--jobs N | --cluster ADDRESS]
    [--poses P] [--pixel-sigma S]``."""
    from selfcal.studies.cluster import add_cluster_args

    sp = subparsers.add_parser(
        "montecarlo",
        help="Monte Carlo of both calibration methods against the Cramer-Rao bound",
        description="One truth (default scenario, analytic path), many noise draws: achieved "
        "tool-tip and parameter errors of the two-stage and the one-step method against the "
        "Cramer-Rao bound. A scenario with a board ([target] board, e.g. "
        "scenarios/mono-charuco.toml) runs the known-board route against its own bound, with "
        "the scenario's board and camera. Writes DIR/runs.csv, summary.md, summary.json, montecarlo.png; "
        "each finished draw goes to DIR/draws.jsonl at once, and the same command again "
        "resumes an interrupted run. "
        "The draws run in local worker processes or, with --cluster, on a Dask cluster. "
        "See docs/bounds.md and docs/cluster.md.",
    )
    sp.add_argument("--draws", type=int, default=100, help="noise draws (default 100)")
    add_scenario_arg(sp, "of the truth (e.g. scenarios/ur5e.toml)")
    sp.add_argument(
        "--out",
        default=None,
        help="output folder (default runs/montecarlo, with --plans runs/montecarlo-plans); the "
        "draws finished there (DIR/draws.jsonl) are not run again",
    )
    sp.add_argument(
        "--jobs", type=int, default=2, help="worker processes (1 = in-process; not with --cluster)"
    )
    add_cluster_args(sp)
    sp.add_argument("--poses", type=int, default=30, help="calibration postures (default 30)")
    sp.add_argument("--pixel-sigma", type=float, default=0.5, help="corner noise, px")
    sp.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="S",
        help=SEED_HELP,
    )
    sp.add_argument(
        "--no-dither",
        action="store_true",
        help="keep the read-back rounding errors identical in every draw (part of the truth)",
    )
    sp.add_argument(
        "--plans",
        action="store_true",
        help="instead: random against D-optimal postures (bounds for 10/20/30 poses, 3 "
        "trajectory seeds; Monte Carlo of --draws draws at 10 and 30 poses)",
    )
    add_json(sp)
    sp.set_defaults(func=_cmd)
    return sp
