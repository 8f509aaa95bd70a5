"""The timeline of one ``selfcal run``: when each stage starts and ends in each process and
thread, with its CPU seconds, to find what the wall clock waits on (issue 32's critical path).

The run is a child process (interpreter start-up counted; ``uv run``'s own ~0.1 s is not). In
it an import hook wraps the stage functions of :data:`STAGES` as their modules load (a caller's
``from ... import`` then binds the wrapped function) and the import of the heavy modules of
:data:`IMPORTS`; every call appends one line to a file shared by the run, its threads and the
processes it forks (the figure worker). Printed: the stages in time order (seconds since the
child was started: start, end, wall, the thread's CPU and the process's CPU over the span), the
per-frame stages summed by thread, the child's user + system CPU (forked processes included),
its wall time and the 1-minute load average before and after.

Run: ``MUJOCO_GL=egl uv run python -m selfcal.benchmarks.speed.run_timeline [SCENARIO] [--out DIR]``.
Wrapping costs a few microseconds a call: the times are the run's, not a benchmark's median
(``selfcal.benchmarks.speed.measure`` measures that).
"""

from __future__ import annotations

import functools
import importlib.abc
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["STAGES", "IMPORTS", "main"]

STAGES: dict[str, tuple[str, ...]] = {
    "selfcal.cli.main": ("cmd_run",),
    "selfcal.plots.figure_pool": (
        "_warm_up",
        "draw_figures",
        "draw_figure",
        "PendingFigure.wait",
        "FigurePool.close",
    ),
    "selfcal.pipeline.run": ("run_acquire", "run_calibrate", "run_report"),
    "selfcal.acquisition.simulator_setup": ("sim_setup",),
    "selfcal.acquisition.backends": ("plan_dataset", "open_robot"),
    "selfcal.acquisition.acquire": ("acquire",),
    "selfcal.acquisition.held_frames": ("HeldFrames.dataset", "HeldFrames.drain"),
    "selfcal.sim.render": ("StereoRenderer.__init__", "StereoRenderer.render"),
    "selfcal.sim.sim_robot": ("SimRobot.capture", "SimRobot._draw_noise", "apply_noise"),
    "selfcal.io.dataset": ("DatasetWriter.add_frame", "_encode_png", "_write_bytes_atomic"),
    "selfcal.io.frame_cache": ("FrameCache.add",),
    "selfcal.calibration.field.detections": ("detect_markers_noise",),
    "selfcal.calibration.field.calibrate": (
        "calibrate_detailed",
        "detect_dataset",
        "_camera_stage",
        "identify",
        "refine_calibration",
        "with_bounds",
        "judge_against_nominal",
    ),
    "selfcal.calibration.field.evaluate": ("evaluate_field",),
    "selfcal.io.calibration": ("write_calibration",),
    "selfcal.io.jsonfile": ("write_report",),
}
"""Module -> the functions (``Class.method`` for a method) timed in it."""

IMPORTS = ("numpy", "cv2", "scipy.sparse", "scipy.linalg", "mujoco", "matplotlib",
           "matplotlib.figure", "selfcal.cli.main", "selfcal.pipeline.run",
           "selfcal.calibration.field.calibrate")  # fmt: skip
"""Modules whose import is timed (nested imports count in the outer one too)."""

PER_FRAME = ("SimRobot.capture", "StereoRenderer.render", "SimRobot._draw_noise", "apply_noise",
             "DatasetWriter.add_frame", "_encode_png", "_write_bytes_atomic", "FrameCache.add",
             "detect_markers_noise")  # fmt: skip
"""Stages run once per frame or image: summed by thread instead of listed."""


class _Recorder:
    """Appends one line per timed call to ``path`` (O_APPEND: the lines of threads and forked
    processes do not mix), times relative to ``t0`` (``time.time()`` of the child's start)."""

    def __init__(self, path: str, t0: float) -> None:
        self.fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        self.t0 = t0

    def timed(self, name: str, f: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(f)
        def run(*args: Any, **kwargs: Any) -> Any:
            t, tc, pc = time.time(), time.thread_time(), time.process_time()
            try:
                return f(*args, **kwargs)
            finally:
                self.write(name, t, tc, pc)

        return run

    def write(self, name: str, t: float, tc: float, pc: float) -> None:
        thread = threading.current_thread().name
        line = (f"{os.getpid()}\t{thread}\t{t - self.t0:.4f}\t{time.time() - self.t0:.4f}\t"
                f"{time.thread_time() - tc:.4f}\t{time.process_time() - pc:.4f}\t{name}\n")  # fmt: skip
        os.write(self.fd, line.encode())


class _Hook(importlib.abc.MetaPathFinder):
    """Times the import of :data:`IMPORTS` and wraps :data:`STAGES` once their module ran."""

    def __init__(self, rec: _Recorder) -> None:
        self.rec = rec

    def find_spec(self, name: str, path: Sequence[str] | None, target: Any = None) -> Any:
        if name not in STAGES and name not in IMPORTS:
            return None
        for finder in sys.meta_path:
            find = None if finder is self else getattr(finder, "find_spec", None)
            spec = None if find is None else find(name, path, target)
            if spec is not None:
                break
        else:
            return None
        loader: Any = spec.loader
        rec, exec_module = self.rec, loader.exec_module

        def timed_exec(module: Any) -> None:
            t, tc, pc = time.time(), time.thread_time(), time.process_time()
            exec_module(module)
            rec.write(f"import {name}", t, tc, pc)
            for attr in STAGES.get(name, ()):
                owner, _, method = attr.rpartition(".")
                where = getattr(module, owner) if owner else module
                raw = where.__dict__[method] if owner else getattr(module, method)
                if isinstance(raw, (classmethod, staticmethod)):
                    setattr(where, method, type(raw)(rec.timed(attr, raw.__func__)))
                else:
                    setattr(where, method, rec.timed(attr, raw))

        setattr(loader, "exec_module", timed_exec)  # noqa: B010 - a method replaced
        return spec


def _child(argv: list[str]) -> int:
    """The traced ``selfcal`` command (``TIMELINE_FILE``, ``TIMELINE_T0`` from the parent)."""
    rec = _Recorder(os.environ["TIMELINE_FILE"], float(os.environ["TIMELINE_T0"]))
    rec.write("interpreter started", time.time(), time.thread_time(), time.process_time())
    sys.meta_path.insert(0, _Hook(rec))
    from selfcal.cli.main import script

    sys.argv = ["selfcal", *argv]
    try:
        return script()
    finally:
        rec.write("main returned", time.time(), 0.0, 0.0)


PHASES = (
    ("start-up: interpreter, selfcal.cli.main", None, ("cmd_run", 2)),
    ("imports of the run (figure worker forked)", ("cmd_run", 2), ("run_acquire", 2)),
    ("simulator set-up and plan", ("run_acquire", 2), ("acquire", 2)),
    ("acquisition: render, noise, PNG, detection", ("acquire", 2), ("acquire", 3)),
    ("calibration", ("run_calibrate", 2), ("run_calibrate", 3)),
    ("report before the figures", ("run_report", 2), ("PendingFigure.wait", 2)),
    ("waiting for the figure processes", ("PendingFigure.wait", 2), ("PendingFigure.wait", 3)),
    ("report after the figures, closing", ("PendingFigure.wait", 3), ("main returned", 3)),
    ("interpreter exit", ("main returned", 3), None),
)
"""The main thread's phases, one after another: (label, from, to), each an edge (2 start,
3 end) of a stage's first call (last call for an end), None the child's start or exit."""


def critical_path(rows: list[list[str]], wall: float) -> list[str]:
    """The main thread's :data:`PHASES` with their wall seconds: what the run's wall time is
    made of (a phase whose stage was not called is left out)."""
    main = [r for r in rows if r[0] == rows[0][0] and r[1] == "MainThread"]

    def at(edge: tuple[str, int] | None, last: bool) -> float | None:
        if edge is None:
            return wall if last else 0.0
        hits = [float(r[edge[1]]) for r in main if r[6] == edge[0]]
        return (max(hits) if last else min(hits)) if hits else None

    out = ["critical path (main thread)                    from      to    wall"]
    for label, a, b in PHASES:
        t0, t1 = at(a, a is not None and a[1] == 3), at(b, b is None or b[1] == 3)
        if t0 is not None and t1 is not None:
            out.append(f"{label:44s} {t0:7.3f} {t1:7.3f} {t1 - t0:7.3f}")
    return out


def report(lines: list[str], wall: float) -> str:
    """The timeline text of the recorded ``lines`` (see the module docstring) of a run of
    ``wall`` seconds."""
    rows = sorted((r.split("\t") for r in lines if r.strip()), key=lambda r: float(r[2]))
    pids: dict[str, str] = {}
    for r in rows:
        pids.setdefault(r[0], "main" if not pids else f"p{len(pids)}")
    out = [*critical_path(rows, wall), ""]
    out += ["process thread          start     end    wall  thrCPU procCPU  stage"]
    frames: dict[tuple[str, str, str], list[float]] = {}
    for pid, thread, a, b, tc, pc, name in rows:
        if name in PER_FRAME:  # calls, first start, last end, wall, thread CPU
            acc = frames.setdefault((pids[pid], thread, name), [0, float(a), 0.0, 0.0, 0.0])
            acc[0] += 1
            acc[2] = max(acc[2], float(b))
            acc[3] += float(b) - float(a)
            acc[4] += float(tc)
            continue
        out.append(f"{pids[pid]:7s} {thread[:14]:14s} {float(a):7.3f} {float(b):7.3f} "
                   f"{float(b) - float(a):7.3f} {float(tc):7.3f} {float(pc):7.3f}  {name}")  # fmt: skip
    out += ["", "per frame, summed by thread:     calls   first    last    wall  thrCPU"]
    for (proc, thread, name), acc in sorted(frames.items(), key=lambda kv: -kv[1][4]):
        out.append(f"{proc:7s} {thread[:14]:14s} {name:24s} {int(acc[0]):4d} "
                   + " ".join(f"{v:7.3f}" for v in acc[1:]))  # fmt: skip
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    if args[:1] == ["--child"]:
        sys.exit(_child(args[1:]))
    p = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    p.add_argument("scenario", nargs="?", help="as `selfcal run` takes it (default: the default)")
    p.add_argument("--out", type=Path, help="the run's folder (default: a new temporary one)")
    a = p.parse_args(args)
    with tempfile.TemporaryDirectory(prefix="selfcal-timeline-") as tmp:
        out = a.out or Path(tmp) / "run"
        log = Path(tmp) / "timeline.tsv"
        cmd = [sys.executable, "-m", "selfcal.benchmarks.speed.run_timeline", "--child", "run",
               *([a.scenario] if a.scenario else []), "--out", str(out)]  # fmt: skip
        load = os.getloadavg()[0]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.time()
        env = {**os.environ, "TIMELINE_FILE": str(log), "TIMELINE_T0": repr(t0)}
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
        wall = time.time() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            print(done.stderr[-3000:], file=sys.stderr)
        print(report(log.read_text().splitlines(), wall))
    user, sys_ = after.ru_utime - before.ru_utime, after.ru_stime - before.ru_stime
    print(f"\nselfcal run (exit {done.returncode}): wall {wall:.2f} s, CPU {user + sys_:.2f} s "
          f"(user {user:.2f} + system {sys_:.2f}, every process); 1-minute load average "
          f"{load:.1f} before, {os.getloadavg()[0]:.1f} after ({os.cpu_count()} CPUs)")  # fmt: skip


if __name__ == "__main__":
    main()
