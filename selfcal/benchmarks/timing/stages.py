"""Benchmark of the whole pipeline by stage, for 10, 30, 100 and 300 poses (rendered path).

Stages: render (drive the simulated robot and render + store the stereo pairs, i.e. the
acquisition), detect (ArUco corners in every image), self-calibrate (``selfcal.calibration.field.self_calibration``: focal
length, poses, rig, points, scale), identify (MCPC least squares), report (against the truth).
``calibrate (CLI)`` is ``selfcal calibrate`` end to end on the same dataset (detect +
self-calibrate + identify + the output document), a cross-check of the sum. Prints a Markdown
table with the machine (CPU count, CPU model). Not a test.

Run: ``MUJOCO_GL=egl uv run python -m selfcal.benchmarks.timing.stages [--poses 10 30 100 300] [--write-doc]``;
``--write-doc`` writes the table, with the date, the command and the load average, into
docs/performance.md between the ``benchmark_stages`` markers.
"""

from __future__ import annotations

import datetime
import os
import platform
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.field.calibrate import detect_dataset
from selfcal.calibration.field.self_calibration import Observations, self_calibrate
from selfcal.calibration.identify import identify
from selfcal.config.scenario import load_scenario
from selfcal.io.dataset import Dataset
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.pipeline.run import run_acquire, run_calibrate, run_report
from selfcal.robot.definition import load_robot


def machine() -> str:
    """``N CPU(s), <model>`` from os.sched_getaffinity and /proc/cpuinfo."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    model = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{n} CPU(s) (nproc), {model}"


def bench(poses: int, root: Path) -> dict:
    s = load_scenario(None, {"trajectory": {"poses": poses}})
    t = {}
    t0 = time.perf_counter()
    run_acquire(s, root, quiet=True)
    t["render"] = time.perf_counter() - t0

    ds = Dataset.open(root)
    t0 = time.perf_counter()
    dets = detect_dataset(ds).detections
    t["detect"] = time.perf_counter() - t0

    robot = load_robot(ds.info.robot_model)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    q = np.radians(ds.joints_deg)
    pos = {int(i): k for k, i in enumerate(ds.indices)}
    obs = Observations.from_corners(
        {(pos[i], c): m for (i, c), m in dets.items() if i in pos}, n_configs=len(ds.indices)
    )
    W, H = ds.info.resolution
    t0 = time.perf_counter()
    sc = self_calibrate(
        obs,
        W,
        H,
        scale_markers=(int(ds.info.scale_ids[0]), int(ds.info.scale_ids[1])),
        scale_distance_m=ds.info.scale_length_m,
        nominal_cam_positions=fk_tool(nominal, q)[:, :3, 3],
    )
    t["self-calibrate"] = time.perf_counter() - t0
    reg = sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0]
    used = np.flatnonzero(reg)
    t0 = time.perf_counter()
    identify(nominal, q[used], sc.T_world_cam[used, 0])
    t["identify"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    cal = run_calibrate(root, quiet=True, raise_failed=False)
    t["calibrate (CLI)"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    rep = run_report(root, quiet=True)
    t["report"] = time.perf_counter() - t0
    return {
        "poses": poses,
        "frames_used": cal.dataset.frames_used,
        "times": t,
        "fx_err": rep["intrinsics"]["fx"]["estimate"] - rep["intrinsics"]["fx"]["truth"],
        "cal_rms": rep["validation"]["tool_tip_error_mm"]["calibrated"]["rms"],
    }


STAGES = ("render", "detect", "self-calibrate", "identify", "report", "calibrate (CLI)")


def table(results: list[dict]) -> str:
    head = (
        "| poses | frames used | "
        + " | ".join(f"{s} (s)" for s in STAGES)
        + " | fx error (px) | validation RMS (mm) |"
    )
    lines = [head, "|" + "---|" * (len(STAGES) + 4)]
    for r in results:
        lines.append(
            f"| {r['poses']} | {r['frames_used']} | "
            + " | ".join(f"{r['times'][s]:.2f}" for s in STAGES)
            + f" | {r['fx_err']:+.3f} | {r['cal_rms']:.3f} |"
        )
    return "\n".join(lines)


COMMAND = "MUJOCO_GL=egl uv run python -m selfcal.benchmarks.timing.stages --write-doc"


def main() -> None:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, nargs="+", default=[10, 30, 100, 300])
    ap.add_argument("--write-doc", action="store_true", help="write docs/performance.md's table")
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    results = []
    with tempfile.TemporaryDirectory(prefix="selfcal-bench-") as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n in args.poses:
            results.append(bench(n, Path(d) / f"p{n}"))
            print(
                f"{n} poses: "
                + ", ".join(f"{k} {v:.2f} s" for k, v in results[-1]["times"].items()),
                flush=True,
            )
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    head = (
        f"Measured {when} with `{COMMAND}` ({machine()}; 1-minute load average "
        f"{load_before:.1f} before, {os.getloadavg()[0]:.1f} after; default scenario: rendered "
        "640x480 stereo, 20 markers; MUJOCO_GL=" + os.environ.get("MUJOCO_GL", "") + ")."
    )
    block = head + "\n\n" + table(results)
    print()
    print(block)
    if args.write_doc:
        from selfcal.benchmarks.doc_blocks import ROOT, write_block

        write_block(ROOT / "docs" / "performance.md", block, "benchmark_stages")


if __name__ == "__main__":
    main()
