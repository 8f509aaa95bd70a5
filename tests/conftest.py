"""Shared test setup: headless rendering through MuJoCo's EGL backend, and the golden-file option.

Tiers (see README): ``tests/unit`` pure functions, ``tests/integration`` whole paths on small data,
tests marked ``slow`` (rendering-heavy studies and Monte Carlo), ``tests/real`` (marked ``real``:
real recordings through the CLI). ``uv run pytest`` runs the first two; ``.ci/run`` runs all four.
"""

from __future__ import annotations

import gc
import json
import math
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

# Where PYTHONDONTWRITEBYTECODE is set (the CI images, this project's machines) no process wrote
# bytecode, so every test process (each xdist worker, each tier) compiled selfcal and rewrote and
# compiled the asserts of every test module again: `uv run pytest --collect-only -q -n 0` took
# 11.0-13.6 CPU s (user+sys) so, 5.7 s reading the cache (`uv sync --compile-bytecode` compiles
# the dependencies only). The test processes write it (git-ignored __pycache__ folders; pytest
# keeps its rewritten test modules apart by a "-pytest-<version>" tag), as a checkout without
# that variable does. Before hypothesis is imported: pytest rewrites the asserts of every module
# of a distribution that registers a pytest plugin, hypothesis's 73 with them, and imported
# after this line they too are rewritten once, not in every test process (`pytest
# --collect-only -q -n 0`: 4.1-4.8 CPU s before, 3.7-4.3 after, load 13-19).
sys.dont_write_bytecode = False

from hypothesis import settings  # noqa: E402  (after the line above: see its comment)

# Property and fuzz tests (hypothesis) explore new inputs on every local run; CI runs them
# derandomized (.ci/run sets HYPOTHESIS_PROFILE=ci), so a landing is decided by the code, not by
# the day's draw. What a local run finds is kept in .hypothesis/ and becomes a regression test.
settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
HYPOTHESIS_PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "default")
settings.load_profile(HYPOTHESIS_PROFILE)


# `uv run pytest --all-examples` (.ci/run's slow-tier step): every property test draws its full
# example count; without it a sixth. Read by `examples`, set before any test module is imported.
ALL_EXAMPLES = False


def examples(count: int) -> int:
    """A property test's ``max_examples``: ``count`` in a run given ``--all-examples`` (.ci/run
    runs every property test so in its slow-tier step, ``-m 'slow or property'``), a sixth of it
    (at least 3) otherwise, in the default tier under either profile. The property tests took 25
    of the default tier's 249 CPU s locally (process_time per test, load 6-8), and at their full
    count under the ci profile 30.3 CPU s, a third of it 13.9 (`HYPOTHESIS_PROFILE=ci uv run
    pytest -n 0 --cpu-durations DIR` on their 18 modules, load 20-30); the default tier's 51
    took 10.4 CPU s at a third, 6.5 at a sixth (the same command with ``-m "property and not
    slow and not real"``, load 12-14). A sixth still finds what the properties are for: with
    ``_axis_number``'s digit cap removed (selfcal/hw/acl/errors.py), test_acl_fuzz's
    test_error_lines_are_total fails at its 50 examples under either profile. The default tier
    draws a sixth (derandomized in CI), the slow tier the whole count, and a local run draws new
    examples each time, so the runs together still explore. A test that sets ``derandomize=True`` itself
    (test_kinematics, test_ik) draws the same first sixth on every default-tier run: its later
    examples are tried by the slow tier only."""
    return count if ALL_EXAMPLES else max(3, -(-count // 6))


# `uv run pytest --cpu-durations DIR`: each test phase's CPU seconds (tests/cpu_durations.py)
pytest_plugins = ["cpu_durations"]

T = TypeVar("T")

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"

# Keys whose values are measurements of this machine, not results of the estimation.
VOLATILE_KEYS = frozenset({"seconds"})
# An LM solve's iteration count follows the floating-point path near the minimum: warm-started,
# the rendered golden run took 20 or 23 joint iterations depending on the BLAS threads' rounding
# (the same minimum, every estimate within the golden tolerance), so counts compare within a
# quarter of the golden one (at least 3): a solve that needs many more iterations still fails.
ITERATION_KEYS = frozenset({"iterations"})


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--regen-golden",
        action="store_true",
        help="rewrite tests/golden/* from the current code instead of comparing against them",
    )
    parser.addoption(
        "--all-examples",
        action="store_true",
        help="property tests draw their full example count (`examples`), not a sixth",
    )


def pytest_configure(config: pytest.Config) -> None:
    global ALL_EXAMPLES
    ALL_EXAMPLES = bool(config.getoption("--all-examples"))


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every hypothesis test is marked ``property`` (before ``-m`` selects), so .ci/run's slow
    tier selects them with ``-m 'slow or property' --all-examples`` at their full count."""
    for item in items:
        if getattr(getattr(item, "obj", None), "is_hypothesis_test", False):
            item.add_marker(pytest.mark.property)


@pytest.fixture
def golden(request: pytest.FixtureRequest):
    """``golden(name, produced_dict)``: compare with tests/golden/<name> (or rewrite it)."""
    regen = request.config.getoption("--regen-golden")

    def check(name: str, produced: dict, *, rtol: float = 1e-6, atol: float = 1e-9) -> None:
        path = GOLDEN_DIR / name
        if regen:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(produced, indent=1, sort_keys=True) + "\n")
            return
        if not path.exists():
            pytest.fail(f"{path} missing: run pytest with --regen-golden once to write it")
        expected = json.loads(path.read_text())
        problems = compare_json(expected, json.loads(json.dumps(produced)), rtol=rtol, atol=atol)
        assert not problems, f"{name} differs from the golden file:\n" + "\n".join(problems[:40])

    return check


@pytest.fixture(scope="session", autouse=True)
def _leaks_collected_in_the_last_test() -> Iterator[None]:
    """The garbage collector run once more in the last test's teardown: an unclosed file or
    socket still uncollected then raises its ResourceWarning in a test (an error by pyproject's
    ``filterwarnings``), where pytest-xdist reports it; at a worker's session end (pytest's own
    last collection) it was lost, the run passing."""
    yield
    gc.collect()


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread_per_test_process() -> None:
    """Each test process computes with ``SELFCAL_THREADS`` (else 1) BLAS threads from its first
    test on, as every ``selfcal`` process does (selfcal/threads.py). The pools started at the
    core count and shrank only once some test ran ``cli.main``, so what came before ran two
    OpenBLAS threads in each of the two xdist workers on two cores: the default scenario's
    calibration took 14.2 CPU s so against 1.2 s with one thread (time.process_time around
    run_calibrate, under load). Only this process's pools: the environment is left alone, so a
    test of what a child process or worker pool sets (tests/integration/test_threads.py) still
    sees only what the code sets. scipy's own OpenBLAS is loaded first so the limit reaches it."""
    import scipy.linalg  # noqa: F401  (its own OpenBLAS, loaded before the limit)
    from threadpoolctl import threadpool_limits

    from selfcal.threads import thread_count

    threadpool_limits(limits=thread_count())


def shared_run(
    tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], T]
) -> T:
    """``build(folder)`` once per test run, not once per xdist worker: a deterministic session
    fixture's value (picklable; its files in ``folder``) is built by the first worker that asks,
    under a file lock in the run's temporary folder, which every worker shares
    (``getbasetemp().parent``, pytest-xdist's documented pattern; ``fcntl.flock`` for the lock),
    and the others wait for it and read the pickle. Each worker built the default scenario's
    two calibrations before (1.5-1.9 CPU s each with one BLAS thread). Without xdist it builds
    in the process's own temporary folder. A failed build leaves no pickle: the next worker tries again
    (and fails the same way)."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        return build(tmp_path_factory.mktemp(name))
    import fcntl
    import pickle

    root = tmp_path_factory.getbasetemp().parent
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        done = root / name / "built.pickle"
        if done.is_file():
            return pickle.loads(done.read_bytes())
        (root / name).mkdir(exist_ok=True)
        value = build(root / name)
        done.write_bytes(pickle.dumps(value))
        return value


@pytest.fixture(scope="session")
def shared(tmp_path_factory) -> Callable[[str, Callable[[Path], T]], T]:
    """``shared(name, build)``: :func:`shared_run` for a test module's own fixture (a module
    fixture whose value is deterministic and picklable, and which no test changes), built once
    per test run instead of once per xdist worker that runs one of the module's tests. ``name``
    is unique in the run (the module's name and the fixture's)."""

    def run(name: str, build: Callable[[Path], T]) -> T:
        return shared_run(tmp_path_factory, name, build)

    return run


@pytest.fixture(scope="session")
def default_analytic(tmp_path_factory):
    """The default scenario on the analytic path (0.5 px corner noise, quantised joints) acquired,
    calibrated and reported once per test run (the golden files', the pipeline's and the
    compensation's tests each ran this same run): (folder, the calibration result, what
    ``run_calibrate`` printed on stderr, the report). Read it, never write into the folder."""
    import contextlib
    import io

    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

    def build(folder: Path):
        out = folder / "ds"
        run_acquire(load_scenario(overrides={"noise": {"render": False}}), out, quiet=True)
        said = io.StringIO()
        with contextlib.redirect_stderr(said):
            result = run_calibrate(out, quiet=False)
        return out, result, said.getvalue(), run_report(out, quiet=True)

    return shared_run(tmp_path_factory, "default-analytic", build)


@pytest.fixture(scope="session")
def default_rendered(tmp_path_factory):
    """The default scenario as it is (rendered images, detected) acquired, calibrated and
    reported once per test run: the rendered golden files' test and the pipeline's rendered
    accuracy test (both slow) each ran this same run. (folder, the report). Read it, never
    write into the folder."""
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

    def build(folder: Path):
        out = folder / "ds"
        run_acquire(load_scenario(), out, quiet=True)
        run_calibrate(out, quiet=True)
        return out, run_report(out, quiet=True)

    return shared_run(tmp_path_factory, "default_rendered", build)


@pytest.fixture(scope="session")
def default_analytic_15(tmp_path_factory):
    """The default scenario on the analytic path with 15 postures (0.5 px corner noise,
    quantised joints, 20 validation postures), calibrated and reported with figures once per
    test run (the main job's outputs and the exports each acquired and calibrated this same
    run; the validation postures are drawn apart and never calibrate): (folder, the report).
    Read it, never write into the folder: copy it (tests/integration/test_job_report.py)."""
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

    def build(folder: Path):
        out = folder / "ds"
        s = load_scenario(overrides={"noise": {"render": False}, "trajectory": {"poses": 15}})
        run_acquire(s, out, quiet=True)
        run_calibrate(out, quiet=True, figures=True)
        return out, run_report(out, quiet=True, figures=True)

    return shared_run(tmp_path_factory, "default-analytic-15", build)


@pytest.fixture(scope="session")
def mono_charuco_15(shared):
    """scenarios/mono-charuco.toml (the ER-4u, one wrist camera with a lens, a ChArUco board) on
    the analytic path with 15 postures, acquired, calibrated and reported once per test run
    (tests/integration/test_board_analytic.py's tests and `selfcal plan --check`'s each ran
    it): (the folder, what ``run_all`` returned). Read it, never write into the folder."""
    from selfcal.config.scenario import load_scenario, scenarios_dir
    from selfcal.pipeline.run import run_all

    def build(folder: Path):
        out = folder / "run"
        s = load_scenario(scenarios_dir() / "mono-charuco.toml",
                          {"noise": {"render": False}, "trajectory": {"poses": 15}})  # fmt: skip
        return out, run_all(s, out, quiet=True, figures=False)

    return shared("conftest-mono_charuco_15", build)


@pytest.fixture(scope="session")
def default_exact_joints(tmp_path_factory) -> Path:
    """The default scenario on the analytic path with 0.5 px corner noise (seed 4) and exact joint
    read-back, acquired (not calibrated) once per test run: the folder of the dataset. The
    tracker tests (tests/integration/test_calibrate_tracker.py, test_joint_tracker.py) each
    acquired this same dataset. Never write into it: copy it (shutil.copytree)."""
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire

    def build(folder: Path) -> Path:
        out = folder / "ds"
        noise = {"render": False, "pixel_sigma": 0.5, "seed": 4, "quantize_joints": False}
        run_acquire(load_scenario(overrides={"noise": noise}), out, quiet=True)
        return out

    return shared_run(tmp_path_factory, "default-exact-joints", build)


@pytest.fixture(scope="session")
def default_noise_free(tmp_path_factory):
    """The default scenario without noise (analytic corners, no pixel noise, joints not
    quantised) acquired, calibrated and reported once per test run (the pipeline's and the
    joint refinement's noise-free tests each ran this same run): (folder, the calibration
    result, the report). Copy the folder to change it (`selfcal report` on it writes the same
    report.json again)."""
    from selfcal.config.scenario import load_scenario
    from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

    def build(folder: Path):
        out = folder / "ds"
        noise = {"render": False, "pixel_sigma": 0.0, "quantize_joints": False}
        run_acquire(load_scenario(overrides={"noise": noise}), out, quiet=True)
        return out, run_calibrate(out, quiet=True), run_report(out, quiet=True)

    return shared_run(tmp_path_factory, "default-noise-free", build)


@pytest.fixture(scope="session")
def paper_montecarlo_12(tmp_path_factory):
    """The paper's scenario's Monte Carlo of 8 noise draws (seeds 1-8) of 12 postures, the truth
    and the trajectory of seed 1, in a local pool of 2 processes (one BLAS thread each), once
    per test run: (rows, summary). The bound's consistency test takes every draw and the
    cluster's tests seeds 5-7, which they computed again before (a draw is a function of its
    settings alone). Read them, never change them."""

    def build(_folder: Path):
        from selfcal.studies.montecarlo.run import run_montecarlo

        return run_montecarlo(8, None, poses=12, jobs=2, quiet=True)

    return shared_run(tmp_path_factory, "paper-montecarlo-12", build)


@pytest.fixture(scope="session")
def ur5e_wrist_plan(tmp_path_factory):
    """The plan benchmark's UR5e cell (selfcal.benchmarks.plan.add.wrist_cell: a 60 deg 640 x 480
    camera, the ChArUco board on the table where home looks) and its plan of 8 postures from 80
    candidates (seed 3, workspace 20, joint sigma 0.01 deg), made once per test run: the plan
    tests of --add, the spread and the selection each made this same plan (3.0 CPU s each,
    time.process_time, one BLAS thread): (setup, plan). Read them, never change them."""

    def build(_folder: Path):
        import numpy as np

        from selfcal.benchmarks.plan.add import wrist_cell
        from selfcal.calibration.board.plan.planner import plan_recording

        setup, _, _ = wrist_cell()
        sigma = np.full(6, np.radians(0.01))
        return setup, plan_recording(
            setup, 8, seed=3, candidates=80, workspace=20, joint_sigma=sigma
        )

    return shared_run(tmp_path_factory, "ur5e-wrist-plan", build)


def compare_json(expected, actual, *, rtol: float, atol: float, path: str = "") -> list[str]:
    """Differences between two JSON trees: numbers within ``atol + rtol * max(|a|, |b|)``.

    Keys of ``expected`` must be present in ``actual`` (new keys are allowed); strings, booleans
    and None must be equal; VOLATILE_KEYS are skipped; ITERATION_KEYS compare within a quarter.
    """
    out: list[str] = []
    if isinstance(expected, dict):
        if not isinstance(actual, dict):
            return [f"{path}: expected an object, got {type(actual).__name__}"]
        for k, v in expected.items():
            if k in VOLATILE_KEYS:
                continue
            if k not in actual:
                out.append(f"{path}.{k}: missing")
                continue
            if k in ITERATION_KEYS and isinstance(v, int) and isinstance(actual[k], int):
                if abs(actual[k] - v) > max(3, v // 4):
                    out.append(f"{path}.{k}: {actual[k]} != golden {v} (within {max(3, v // 4)})")
                continue
            out += compare_json(v, actual[k], rtol=rtol, atol=atol, path=f"{path}.{k}")
        return out
    if isinstance(expected, list):
        if not isinstance(actual, list) or len(actual) != len(expected):
            return [f"{path}: expected a list of {len(expected)}, got {actual!r:.60}"]
        for i, (e, a) in enumerate(zip(expected, actual)):
            out += compare_json(e, a, rtol=rtol, atol=atol, path=f"{path}[{i}]")
        return out
    numeric = (int, float)
    if isinstance(expected, numeric) and not isinstance(expected, bool):
        if not isinstance(actual, numeric) or isinstance(actual, bool):
            return [f"{path}: expected a number, got {actual!r}"]
        if math.isnan(expected) and math.isnan(actual):
            return []
        tol = atol + rtol * max(abs(expected), abs(actual))
        if not abs(expected - actual) <= tol:
            return [f"{path}: {actual!r} != golden {expected!r} (tolerance {tol:.3g})"]
        return []
    if expected != actual:
        return [f"{path}: {actual!r} != golden {expected!r}"]
    return []


def start_emulate_cli(argv: list[str], timeout_s: float = 60.0):
    """Run ``selfcal emulate ARGV`` in a thread until it prints ``Ctrl-C``.

    Returns (thread, stop event, its stdout buffer, [exit code once stopped]); set the event and
    join the thread to stop it.
    """
    import argparse
    import io
    import threading
    import time
    from contextlib import redirect_stdout

    from selfcal.cli.hw import register

    parser = argparse.ArgumentParser(prog="selfcal")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["emulate", *argv])
    stop, buf, rc = threading.Event(), io.StringIO(), []

    def serve() -> None:
        with redirect_stdout(buf):
            rc.append(args.func(args, stop))

    th = threading.Thread(target=serve)
    th.start()
    deadline = time.monotonic() + timeout_s
    while "Ctrl-C" not in buf.getvalue():
        if not th.is_alive() or time.monotonic() > deadline:
            stop.set()
            th.join(timeout=10)
            raise AssertionError(f"selfcal emulate did not start: {buf.getvalue()}")
        time.sleep(0.02)
    return th, stop, buf, rc
