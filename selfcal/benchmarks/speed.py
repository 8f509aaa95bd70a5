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

With ``--against REF`` also git ``REF`` measured the same way in a temporary worktree, both
side by side, and issue 32's goals met or not (:mod:`selfcal.benchmarks.speed_against`);
``--memory`` adds ``selfcal calibrate``'s peak memory per posture. The checkout's ``selfcal/`` is
compiled first, as ``pip install`` compiles a wheel (where ``PYTHONDONTWRITEBYTECODE`` is set,
every process would compile it again).

Writes the table to docs/performance.md (``--write-docs``) and into README.md between the
``benchmark_speed`` markers (``--write-readme``). It exits 1 when a measured figure is more than
1.3x off the one the README states, unless ``--write-readme`` replaces them (``--check``: then
too). The 1-minute load average before and after each
part is printed and written with the table: the machines are shared.

Run: ``MUJOCO_GL=egl uv run python -m selfcal.benchmarks.speed [--large] [--with-pybotics]
[--write-docs] [--write-readme] [--check] [--against REF] [--memory]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import os
import re
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
from selfcal.io.atomic import write_text_atomic

BEGIN, END = "<!-- benchmark_speed: begin -->", "<!-- benchmark_speed: end -->"
TOLERANCE = 1.3
COMMAND = "MUJOCO_GL=egl uv run python -m selfcal.benchmarks.speed --write-docs --write-readme"


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
    own environment): one row of :func:`selfcal.benchmarks.tracker.run` and its note (the
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


def measure(args: argparse.Namespace) -> dict:
    """Every figure of the table, with the load average around each part."""
    script = Path(sys.executable).parent / "selfcal"  # the installed console script
    selfcal = [str(script)] if script.is_file() else [sys.executable, "-m", "selfcal.cli.main"]
    fig: dict = {"load": [load()]}
    fig["help"] = process_seconds([*selfcal, "--help"], args.repeat)
    fig["fk"] = process_seconds([*selfcal, "fk", "--joints", "10,-20,30,-40,50"], args.repeat)
    print(f"selfcal --help {fig['help']} s, selfcal fk {fig['fk']} s (median wall, CPU)")
    fig["load"].append(load())
    with tempfile.TemporaryDirectory(prefix="selfcal-speed-") as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        root = Path(d)
        if not args.skip_run:
            fig["run"] = run_seconds(selfcal, root / "run", args.run_repeat)
            print(f"selfcal run (default scenario) {fig['run']} s (wall, CPU)")
            fig["load"].append(load())
            fig["run_loaded"] = beside_a_busy_process(
                lambda: run_seconds(selfcal, root / "run-loaded", args.run_repeat)
            )
            print(f"selfcal run beside a CPU-bound process {fig['run_loaded']} s (wall, CPU)")
            fig["load"].append(load())
        fig["calibrate"] = calibrate_scaling(args.poses, root)
        fig["load"].append(load())
        fig["ba"] = ba_against_scipy(args.ba_poses, root)
        fig["load"].append(load())
    if args.with_pybotics:
        fig["pybotics"] = pybotics_ratio(args.pybotics_n)
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

    script = Path(sys.executable).parent / "selfcal"
    selfcal = [str(script)] if script.is_file() else [sys.executable, "-m", "selfcal.cli.main"]
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


def table(fig: dict) -> str:
    """The Markdown block (README and docs/performance.md)."""
    when = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    loads = ", ".join(f"{v:.1f}" for v in fig["load"])
    lines = [
        f"Measured {when} with `{COMMAND}` ({os.cpu_count()} CPUs; 1-minute load average "
        f"during the parts: {loads}; 1 BLAS thread).",
        "",
        "| what | seconds |",
        "|---|---|",
        f"| `selfcal --help` (process, median; CPU {fig['help'][1]:.2f} s) | {fig['help'][0]:.2f} |",
        f"| `selfcal fk --joints ...` (process, median; CPU {fig['fk'][1]:.2f} s) | "
        f"{fig['fk'][0]:.2f} |",
    ]
    if "run" in fig:
        lines.append(f"| `selfcal run` default scenario (rendered, 30 poses; process, median; CPU "
                     f"{fig['run'][1]:.2f} s) | {fig['run'][0]:.2f} |")  # fmt: skip
    if "run_loaded" in fig:
        r = fig["run_loaded"][0] / fig["run"][0]
        lines.append(f"| same, beside a CPU-bound process (CPU {fig['run_loaded'][1]:.2f} s; "
                     f"{r:.2f}x the quiet run) | {fig['run_loaded'][0]:.2f} |")  # fmt: skip
    for r in fig["calibrate"]:
        lines.append(
            f"| `calibrate`, analytic, {r['poses']} poses ({r['used']} used; in-process wall, "
            f"CPU {r['cpu']:.2f} s, {1000 * r['wall'] / r['poses']:.0f} ms/pose) | "
            f"{r['wall']:.2f} |"
        )
    for r in fig["calibrate"]:
        lines.append(f"| acquisition, analytic, {r['poses']} poses | {r['acquire']:.2f} |")
    b = fig["ba"]
    lines += [
        f"| bundle adjustment, {b['poses']} poses ({b['unknowns']} unknowns), engine "
        f"({b['solver']}; cost {b['engine_cost']:.6g}) | {b['engine']:.2f} |",
        f"| same, `scipy.optimize.least_squares` trf + lsmr, sparse Jacobian (cost "
        f"{b['scipy_cost']:.6g}; {b['scipy'] / b['engine']:.1f}x the engine's time) | "
        f"{b['scipy']:.2f} |",
    ]
    if "pybotics" in fig:
        lines += _pybotics_lines(fig["pybotics"])
    return "\n".join(lines)


def _pybotics_lines(r: dict) -> list[str]:
    """The identification rows: ours, and pybotics with the ratio (or why it is missing)."""
    what = f"identification from tracker positions, UR5e, {r['N']} configurations"
    lines = [
        f"| {what}: ours (`identify_tracker`, best of 10; CPU {r['ours_cpu_s']:.4f} s; "
        f"held-out {r['ours_mm']:.3f} mm) | {r['ours_s']:.4f} |"
    ]
    if r["pyb_s"] is None:
        return lines + [f"| same, pybotics: not measured ({r['note']}) | n/a |"]
    return lines + [
        f"| same, {r['note']} `least_squares` in its own environment (best of 3; CPU "
        f"{r['pyb_cpu_s']:.3f} s; held-out {r['pyb_mm']:.3f} mm; {r['pyb_s'] / r['ours_s']:.0f}x "
        f"ours' time, {r['pyb_cpu_s'] / r['ours_cpu_s']:.0f}x by CPU) | {r['pyb_s']:.3f} |"
    ]


def figures_of(text: str) -> dict[str, float]:
    """``what -> seconds`` of a table written by :func:`table` (for --check)."""
    out = {}
    for m in re.finditer(r"^\| (.+?) \| ([0-9.]+) \|$", text, flags=re.M):
        key = re.sub(r"\(.*?\)|cost [0-9.e+-]+|[0-9.]+x", "", m.group(1)).strip()
        out[key] = float(m.group(2))
    return out


def readme_block() -> str:
    text = (ROOT / "README.md").read_text()
    if BEGIN not in text or END not in text:
        return ""
    return text.split(BEGIN, 1)[1].split(END, 1)[0]


def check(new: str, stated: str | None = None) -> list[str]:
    """Figures of the table ``new`` more than TOLERANCE off (either way) those of ``stated``
    (default: the README's block), one sentence each."""
    old = figures_of(readme_block() if stated is None else stated)
    bad = []
    for k, v in figures_of(new).items():
        if k in old and old[k] > 0 and v > 0:
            r = v / old[k]
            if r > TOLERANCE or r < 1 / TOLERANCE:
                bad.append(f"{k}: measured {v:.2f} s, README {old[k]:.2f} s ({r:.2f}x)")
    return bad


def linear_growth(rows: list[dict]) -> str:
    """How `calibrate`'s time grows from the first to the last pose count (1.0 = linear)."""
    a, b = rows[0], rows[-1]
    return (
        f"calibrate {a['poses']} -> {b['poses']} poses: time x{b['wall'] / a['wall']:.1f} "
        f"(wall), x{b['cpu'] / a['cpu']:.1f} (CPU) for poses x{b['poses'] / a['poses']:.1f}"
    )


def add_against_options(ap: argparse.ArgumentParser) -> None:
    """``--against REF``, ``--memory`` and ``--json`` (selfcal/benchmarks/speed_against.py)."""
    ap.add_argument("--against", metavar="REF",
                    help="also measure git REF (commit, branch, tag; HEAD~1: the previous commit) "
                    "in a temporary worktree with its own environment, the same way, and print "
                    "both side by side with the ratio and issue 32's goals met or not")  # fmt: skip
    ap.add_argument("--memory", action="store_true",
                    help="also `selfcal calibrate`'s peak memory (a process at the fewest and "
                    "the most --poses) and its growth per posture; implied by --against")  # fmt: skip
    ap.add_argument(
        "--json",
        metavar="FILE",
        help="write the figures as JSON to FILE and stop (REF's run of --against)",
    )


def against_and_goals(args: argparse.Namespace, fig: dict, argv: list[str]) -> str:
    """Issue 32's goals for ``fig`` and, with ``--against REF``, REF measured by the same
    options ``argv`` side by side (:mod:`selfcal.benchmarks.speed_against`)."""
    from selfcal.benchmarks.speed_against import comparison, measure_ref, ref_argv

    if not args.against:
        return comparison(fig)
    ref, commit = measure_ref(args.against, ref_argv(argv))
    named = commit.startswith(args.against) or args.against.startswith(commit)
    return comparison(fig, ref, args.against if named else f"{args.against} ({commit})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
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
    args = ap.parse_args(argv)
    args.with_pybotics = args.with_pybotics or args.write_docs or args.write_readme
    from selfcal.threads import limit_threads

    limit_threads(None)
    if args.large:
        args.poses = sorted(set(args.poses) | set(LARGE))
    if not args.json:  # as installed (pip compiles); REF's run of --against compiles its own
        from selfcal.benchmarks.speed_against import compile_tree

        compile_tree(ROOT)
    fig = measure(args)
    if args.memory or args.against:
        fig["memory"] = calibrate_memory(args.poses)
    if args.json:  # REF's run of --against
        write_text_atomic(Path(args.json), json.dumps(fig))
        return 0
    block = table(fig)
    growth = linear_growth(fig["calibrate"])
    goals = against_and_goals(args, fig, sys.argv[1:] if argv is None else argv)
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
