"""Speed benchmark of issue 17: command start-up, `selfcal run`, `calibrate` against the pose
count, the bundle adjustment against ``scipy.optimize.least_squares`` and the identification
against pybotics.

Measures, in one run on this machine:

- ``selfcal --help`` and ``selfcal fk`` as whole processes (median of ``--repeat`` runs);
- ``selfcal run`` of the default scenario (rendered, 30 poses) as a whole process, and again
  beside a process that spins one core (the ratio to the quiet run: #17 asks for <= 1.5x), each
  the median of ``--run-repeat`` runs (3);
- ``calibrate`` in-process on analytic-path datasets of the default scenario with 30, 100, 300
  and 1000 poses (``[trajectory] poses``; ``--large`` adds 3000 and 10,000, minutes and ~4 GB),
  wall and CPU seconds, and the acquisition of each;
- the bundle adjustment's last plain least-squares pass (captured inside ``calibrate`` at
  ``--ba-poses``), started off its minimum and solved by the engine (Schur elimination of the
  poses) and by ``least_squares`` (trf, sparse Jacobian, lsmr): the speed ratio at the final
  costs (both printed);
- with ``--with-pybotics`` (implied by ``--write-docs`` and ``--write-readme``, so the published
  table has it): the kinematic identification from tracker positions (UR5e, ``--pybotics-n``
  configurations, 0.1 mm noise) by the project (:func:`selfcal.calibration.tracker.identify.identify_tracker`)
  and by pybotics in its own environment, the way :mod:`selfcal.benchmarks.tracker` runs it
  (``uv run --with pybotics``): fit times (best of repeats, wall and CPU), their ratio and both
  held-out errors (equal accuracy is part of the comparison).

With ``--against REF`` also git ``REF`` measured the same way in a temporary worktree, the two
trees in turn part by part (:data:`PARTS`, ``--rounds`` rounds, each part a process running this
file with ``--part P --json FILE``: :mod:`selfcal.benchmarks.speed.pairs`), both side by side with
the ratio of each pair, and issue 32's goals met or not
(:mod:`selfcal.benchmarks.speed.against`); ``--memory`` adds ``selfcal calibrate``'s peak memory
per posture. What runs for a part (``--json``) imports only modules every commit of the
project has: REF's tree runs it with its own package. The checkout's ``selfcal/`` is
compiled first, as ``pip install`` compiles a wheel (where ``PYTHONDONTWRITEBYTECODE`` is set,
every process would compile it again).

Writes the table to docs/performance.md (``--write-docs``) and into README.md between the
``benchmark_speed`` markers (``--write-readme``). It exits 1 when a measured figure is more than
1.3x off the one the README states, unless ``--write-readme`` replaces them (``--check``: then
too). The 1-minute load average before and after each
part is printed and written with the table: the machines are shared.

Run: ``MUJOCO_GL=egl uv run python -m selfcal.benchmarks.speed.measure [--large] [--with-pybotics]
[--write-docs] [--write-readme] [--check] [--against REF [--rounds N]] [--memory]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import ROOT, write_block

try:  # speed --against runs this file with the reference tree's package, maybe older than usage.py
    from selfcal.benchmarks.usage import benchmark_parser
except ImportError:  # that older tree: argparse names the script by its file

    def benchmark_parser(module_file: str | Path, **kwargs) -> argparse.ArgumentParser:
        """argparse's own parser (``module_file`` unused): a reference tree before usage.py."""
        return argparse.ArgumentParser(**kwargs)  # an older tree's fallback


from selfcal.errors import UsageError
from selfcal.io.atomic import write_text_atomic


def load() -> float:
    """The 1-minute load average."""
    return os.getloadavg()[0]


def process_seconds(argv: list[str], repeat: int) -> tuple[float, float]:
    """Median wall and CPU (user + sys) seconds of ``argv`` as a process (output discarded;
    must exit 0)."""
    walls, cpus = [], []
    for _ in range(repeat):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        walls.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


LARGE = [3000, 10000]
"""The pose counts ``--large`` adds: the growth to 10,000 postures (#32: linear, <= 0.3 MB each)."""


def calibrate_scaling(poses: list[int], root: Path) -> list[dict]:
    """Acquire (analytic path) and calibrate the default scenario at each pose count."""
    from selfcal.calibration.field.calibrate import calibrate
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire

    rows = []
    for n in poses:
        s = load_scenario(None, {"trajectory": {"poses": n}, "noise": {"render": False}})
        out = root / f"analytic{n}"
        t0, c0 = time.perf_counter(), time.process_time()
        run_acquire(s, out, quiet=True)
        # its wall time follows the machine's load and the disk (an fsync per frame): the CPU
        # time (every thread) is what compares two trees side by side on a shared machine
        acq, acq_cpu = time.perf_counter() - t0, time.process_time() - c0
        t0, c0 = time.perf_counter(), time.process_time()
        res = calibrate(out)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rows.append({"poses": n, "used": res.dataset.frames_used, "acquire": acq,
                     "acquire_cpu": acq_cpu, "wall": wall, "cpu": cpu})  # fmt: skip
        print(f"calibrate {n} poses: {wall:.2f} s wall, {cpu:.2f} s CPU (acquire {acq:.2f} s "
              f"wall, {acq_cpu:.2f} s CPU)")  # fmt: skip
    return rows


def off_minimum(problem, seed: int = 1):
    """The same residual blocks, started off the minimum: intrinsics by 1e-2 relative, every
    other coordinate by 1e-2 (also the solver-equivalence test's start)."""
    from selfcal.solver import Problem

    rng = np.random.default_rng(seed)
    blocks = []
    for p in problem.parameters.values():
        scale = 1e-2 * (np.abs(p.value) if p.name == "intrinsics" else 1.0)
        v = p.value + scale * rng.standard_normal(p.size)
        if p.held is not None:
            v[p.held] = p.value[p.held]
        blocks.append(dataclasses.replace(p, value=v))
    return Problem(blocks, problem.residuals)


def ba_against_scipy(poses: int, root: Path) -> dict:
    """Engine vs least_squares (trf, sparse Jacobian) on the last plain bundle adjustment."""
    from scipy.optimize import least_squares

    import selfcal.estimation.bundle_adjust as bundle_adjust
    from selfcal.calibration.field.calibrate import calibrate
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire
    from selfcal.solver import SolverOptions, solve

    out = root / f"analytic{poses}"
    if not (out / "dataset.json").is_file():
        s = load_scenario(None, {"trajectory": {"poses": poses}, "noise": {"render": False}})
        run_acquire(s, out, quiet=True)
    seen = []
    real = bundle_adjust.solve

    def spy(problem, *args, **kwargs):  # any commit's solve signature (--against REF)
        seen.append(problem)
        return real(problem, *args, **kwargs)

    bundle_adjust.solve = spy
    try:
        calibrate(out)
    finally:
        bundle_adjust.solve = real
    prob = off_minimum(seen[-1])
    t0 = time.perf_counter()
    eng = solve(prob, SolverOptions(tol=1e-12, eliminate="poses"))
    t_eng = time.perf_counter() - t0
    t0 = time.perf_counter()
    tols = dict.fromkeys(("ftol", "xtol", "gtol"), 1e-12)
    ls = least_squares(prob.residual_vector, prob.x0, jac=prob.jacobian, method="trf",
                       tr_solver="lsmr", x_scale="jac", max_nfev=200, **tols)  # fmt: skip
    t_sp = time.perf_counter() - t0
    row = {
        "poses": poses,
        "unknowns": prob.n,
        "engine": t_eng,
        "scipy": t_sp,
        "engine_cost": eng.cost,
        "scipy_cost": float(ls.cost),
        "solver": eng.linear_solver,
    }
    print(
        f"bundle adjustment at {poses} poses ({prob.n} unknowns): engine ({eng.linear_solver}) "
        f"{t_eng:.2f} s, cost {eng.cost:.6g}; least_squares trf/lsmr {t_sp:.2f} s, cost "
        f"{ls.cost:.6g}; ratio {t_sp / t_eng:.1f}x"
    )
    return row


def pybotics_ratio(n: int, repeats_ours: int = 10, repeats_pybotics: int = 3) -> dict:
    """The tracker identification at ``n`` configurations, the project against pybotics (in its
    own environment): one row of :func:`selfcal.benchmarks.tracker.compare.run` and its note (the
    pybotics version, or why it did not run)."""
    from selfcal.benchmarks.tracker.compare import run as tracker_run

    rows, note = tracker_run(
        sizes=(n,), repeats_ours=repeats_ours, repeats_pybotics=repeats_pybotics
    )
    row = rows[0] | {"note": note}
    if row["pyb_s"] is not None:
        print(
            f"identification, {n} tracker positions: ours {row['ours_s']:.4f} s (CPU "
            f"{row['ours_cpu_s']:.4f}), held-out {row['ours_mm']:.3f} mm; {note} "
            f"{row['pyb_s']:.3f} s (CPU {row['pyb_cpu_s']:.3f}), held-out {row['pyb_mm']:.3f} mm; "
            f"ratio {row['pyb_s'] / row['ours_s']:.0f}x wall, "
            f"{row['pyb_cpu_s'] / row['ours_cpu_s']:.0f}x CPU"
        )
    else:
        print(f"identification, {n} tracker positions: ours {row['ours_s']:.4f} s; {note}")
    return row


def run_seconds(selfcal: list[str], out: Path, repeat: int) -> tuple[float, float]:
    """Median wall and CPU seconds of ``selfcal run --quiet`` (the default scenario) over
    ``repeat`` runs, each into its own folder ``out-K`` (a single run's CPU varies from run to
    run)."""
    runs = [
        process_seconds([*selfcal, "run", "--quiet", "--out", f"{out}-{k}"], 1)
        for k in range(repeat)
    ]
    return statistics.median(w for w, _ in runs), statistics.median(c for _, c in runs)


def beside_a_busy_process(seconds: Callable[[], tuple[float, float]]) -> tuple[float, float]:
    """``seconds()`` (wall, CPU: :func:`process_seconds`, :func:`run_seconds`) while another
    process spins one core (a CPU-bound neighbour on the shared machine: #17 asks for at most
    1.5x the quiet time)."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)  # the neighbour runs before the command starts
        return seconds()
    finally:
        busy.kill()
        busy.wait()


PARTS = ("start", "run", "run_loaded", "calibrate", "ba", "memory")
"""The benchmark's parts in the order they run (``--part P`` measures one): the start-up
commands, ``selfcal run`` quiet and beside a CPU-bound process, ``calibrate`` at each pose
count, the bundle adjustment against scipy, ``selfcal calibrate``'s peak memory (with
``--memory``). ``--against REF`` runs each in a process of its own, by the two trees in turn
(:mod:`selfcal.benchmarks.speed.pairs`)."""


def _selfcal() -> list[str]:
    """The installed console script of this interpreter's environment (else the module)."""
    script = Path(sys.executable).parent / "selfcal"
    return [str(script)] if script.is_file() else [sys.executable, "-m", "selfcal.cli.main"]


def measure_part(part: str, args: argparse.Namespace, root: Path) -> dict:
    """The figures of one of :data:`PARTS`, measured now (``root``: a new folder for the
    runs' outputs)."""
    selfcal = _selfcal()
    if part == "start":
        fig = {"help": process_seconds([*selfcal, "--help"], args.repeat),
               "fk": process_seconds([*selfcal, "fk", "--joints", "10,-20,30,-40,50"],
                                     args.repeat)}  # fmt: skip
        print(f"selfcal --help {fig['help']} s, selfcal fk {fig['fk']} s (median wall, CPU)")
        return fig
    if part == "run":
        run = run_seconds(selfcal, root / "run", args.run_repeat)
        print(f"selfcal run (default scenario) {run} s (wall, CPU)")
        return {"run": run}
    if part == "run_loaded":
        run = beside_a_busy_process(
            lambda: run_seconds(selfcal, root / "run-loaded", args.run_repeat)
        )
        print(f"selfcal run beside a CPU-bound process {run} s (wall, CPU)")
        return {"run_loaded": run}
    if part == "calibrate":
        return {"calibrate": calibrate_scaling(args.poses, root)}
    if part == "ba":
        return {"ba": ba_against_scipy(args.ba_poses, root)}
    if part == "memory":
        return {"memory": calibrate_memory(args.poses)}
    raise UsageError(f"unknown part {part!r}: one of {', '.join(PARTS)}")


def parts_of(args: argparse.Namespace) -> list[str]:
    """The parts ``args`` asks for, in :data:`PARTS`' order (``--part``: that one alone)."""
    if args.part:
        return [args.part]
    skip = {"run", "run_loaded"} if args.skip_run else set()
    if not (args.memory or args.against):
        skip.add("memory")
    return [p for p in PARTS if p not in skip]


def measure(args: argparse.Namespace, parts: list[str]) -> dict:
    """The figures of ``parts`` (:data:`PARTS`), with the 1-minute load average before the
    first and after each."""
    fig: dict = {"load": [load()]}
    with tempfile.TemporaryDirectory(prefix="selfcal-speed-") as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for part in parts:
            fig |= measure_part(part, args, Path(d))
            fig["load"].append(load())
    return fig


def calibrate_memory(poses: list[int]) -> dict:
    """Peak memory of ``selfcal calibrate`` as a process (its largest resident set, MB) on the
    analytic datasets of the fewest and the most of ``poses``, and its growth per posture
    between them (#32: at most 0.3 MB per posture): ``{"poses": [a, b], "peak_mb": [ma, mb],
    "mb_per_posture": x}``."""
    from selfcal.benchmarks.child import run_child
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire

    selfcal = _selfcal()
    ends = sorted({min(poses), max(poses)})
    peaks = []
    with tempfile.TemporaryDirectory(prefix="selfcal-memory-") as d:
        for n in ends:
            s = load_scenario(None, {"trajectory": {"poses": n}, "noise": {"render": False}})
            out = Path(d) / f"analytic{n}"
            run_acquire(s, out, quiet=True)
            code, _, peak_mb = run_child([*selfcal, "calibrate", "--quiet", str(out)])
            if code != 0:
                raise SystemExit(f"selfcal calibrate {out} exited {code}")
            peaks.append(peak_mb)
    per = (peaks[-1] - peaks[0]) / (ends[-1] - ends[0]) if len(ends) > 1 else peaks[0] / ends[0]
    print(
        f"selfcal calibrate peak memory: {', '.join(f'{n} poses {m:.0f} MB' for n, m in zip(ends, peaks, strict=True))}; {per:.3f} MB per posture"
    )
    return {"poses": ends, "peak_mb": peaks, "mb_per_posture": per}


def add_against_options(ap: argparse.ArgumentParser) -> None:
    """``--against REF``, ``--rounds``, ``--memory``, ``--part`` and ``--json``
    (selfcal/benchmarks/speed/against.py)."""
    ap.add_argument("--against", metavar="REF",
                    help="also measure git REF (commit, branch, tag; HEAD~1: the previous commit) "
                    "in a temporary worktree with its own environment, the two trees in turn "
                    "part by part (--rounds), and print both side by side with the medians, the "
                    "ratio of each pair and issue 32's goals met or not")  # fmt: skip
    ap.add_argument("--rounds", type=int, default=10,
                    help="with --against: rounds of every part by each tree, in turn, the first "
                    "alternating (each `selfcal run` once a round: the rounds replace "
                    "--run-repeat; an even number puts each tree first equally often)")  # fmt: skip
    ap.add_argument("--memory", action="store_true",
                    help="also `selfcal calibrate`'s peak memory (a process at the fewest and "
                    "the most --poses) and its growth per posture; implied by --against")  # fmt: skip
    ap.add_argument("--part", choices=PARTS,
                    help="measure this part of the benchmark alone (a round of --against)")  # fmt: skip
    ap.add_argument(
        "--json",
        metavar="FILE",
        help="write the figures as JSON to FILE and stop (a part of --against)",
    )


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, nargs="+", default=[30, 100, 300, 1000])
    ap.add_argument("--large", action="store_true",
                    help=f"also calibrate at {' and '.join(map(str, LARGE))} poses (issue 32's "
                    "growth to 10,000; minutes, ~4 GB)")  # fmt: skip
    ap.add_argument("--ba-poses", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=5, help="runs of --help and fk (median)")
    ap.add_argument("--skip-run", action="store_true", help="leave out `selfcal run`")
    ap.add_argument("--run-repeat", type=int, default=3,
                    help="runs of `selfcal run`, quiet and beside a CPU-bound process (median)")  # fmt: skip
    ap.add_argument(
        "--with-pybotics",
        action="store_true",
        help="also the identification against pybotics (its own environment, through uv); "
        "implied by --write-docs and --write-readme",
    )
    ap.add_argument("--pybotics-n", type=int, default=100, help="tracker configurations")
    ap.add_argument("--write-docs", action="store_true", help="write docs/performance.md")
    ap.add_argument("--write-readme", action="store_true", help="write the README block")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if > 1.3x off the README even with --write-readme (without "
                    "--write-readme it always does)")  # fmt: skip
    add_against_options(ap)
    argv = sys.argv[1:] if argv is None else argv
    args = ap.parse_args(argv)
    args.with_pybotics = args.with_pybotics or args.write_docs or args.write_readme
    from selfcal.threads import limit_threads

    limit_threads(None)
    if args.large:
        args.poses = sorted(set(args.poses) | set(LARGE))
    if args.json:  # a part of --against (its caller compiled the tree)
        fig = measure(args, parts_of(args))
        write_text_atomic(Path(args.json), json.dumps(fig))
        return 0
    # the rest of this file runs only in this checkout: REF's tree may lack these modules
    from selfcal.benchmarks.speed.against import comparison, compile_tree, measure_against
    from selfcal.benchmarks.speed.table import TOLERANCE, check, command_text, linear_growth, table

    compile_tree(ROOT)  # as installed (pip compiles); REF's tree is compiled by its run
    label, pairs, ref = "", None, None
    if args.against:
        label, fig, ref, pairs = measure_against(args.against, argv, parts_of(args), args.rounds)
    else:
        fig = measure(args, parts_of(args))
    if args.with_pybotics:  # this tree alone
        fig["pybotics"] = pybotics_ratio(args.pybotics_n)
        fig["load"].append(load())
    block = table(fig, command_text(argv))
    growth = linear_growth(fig["calibrate"])
    goals = comparison(fig, ref, label, pairs)
    print()
    print(block)
    print()
    print(growth)
    print()
    print(goals)
    bad = check(block)
    if args.write_docs:
        write_block(ROOT / "docs" / "performance.md", f"{block}\n\n{growth}\n\n{goals}")
    if args.write_readme:
        write_block(ROOT / "README.md", block)
    if bad:
        print(f"\nFIGURES MORE THAN {TOLERANCE}x OFF THE README:", file=sys.stderr)
        for b in bad:
            print(f"  {b}", file=sys.stderr)
        if args.check or not args.write_readme:
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
