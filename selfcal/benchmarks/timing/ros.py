"""Benchmark of ``selfcal import --bag`` on a large bag: does the import stream it?

Writes a ROS bag of ``--size-mb`` megabytes (the project's bag writer, :mod:`selfcal.ros.rosbag`): a
1280x1024 mono8 camera at 30 Hz and joint_states at 1 kHz of a KR 6 R900 that rests 0.6 s at
each of 8 postures and moves at constant speed for several seconds in between, so that most images are taken while
it moves (those are decoded by nobody: the rest test skips them). At rest the camera sees an 11x8
chessboard from a different pose each time (a pinhole camera, the board drawn by homography);
while moving it sees a few fixed noise pictures. Then runs ``selfcal import --bag ... --per-rest 1``
in a child process and prints its wall time and peak resident memory (``ru_maxrss`` of that child
alone, from ``os.wait4`` in a small launcher: :mod:`selfcal.benchmarks.child`) against the bag's size.

Run: ``uv run python -m selfcal.benchmarks.timing.ros [--size-mb 300 2000] [--format ros1]
[--keep DIR]``.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from selfcal.benchmarks.child import run_child
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.robot.definition import load_robot
from selfcal.ros.rosbag import BagWriter
from selfcal.target import Chessboard
from selfcal.transforms import make_pose

W, H, FX = 1280, 1024, 1100.0
CAMERA_HZ, JOINT_HZ = 30, 1000
RESTS, REST_S = 8, 0.6
BOARD = Chessboard((11, 8), 0.015)
TARGET_TOML = 'type = "chessboard"\ninner_corners = [11, 8]\nsquare_mm = 15.0\n'
ROBOT = "kr6-r900"
NS = 1_000_000_000


def _board_view(k: int, rng: np.random.Generator) -> np.ndarray:
    """The board seen by a pinhole camera from the ``k``-th pose (tilted up to 25 deg)."""
    img = BOARD.image(px_per_mm=6.0)
    ppm, (x0, y0) = img.px_per_m, img.extent_m[:2]
    _, pts = BOARD.layout()
    c = (pts.max(axis=0) + pts.min(axis=0)) / 2
    ax, ay = np.radians(rng.uniform(-25, 25, 2))
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    R = Rx @ Ry
    T = make_pose(R, -R @ c + [rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), 0.45])
    K = np.array([[FX, 0, W / 2 - 0.5], [0, FX, H / 2 - 0.5], [0, 0, 1]])
    A = np.array([[1 / ppm, 0, x0 + 0.5 / ppm], [0, 1 / ppm, y0 + 0.5 / ppm], [0, 0, 1]])
    Hm = K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
    out = cv2.warpPerspective(img.pixels, Hm, (W, H), flags=cv2.INTER_AREA, borderValue=170)
    out = out.astype(float) + rng.normal(0, 2.0, (H, W))
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def write_bag(path: Path, size_mb: float, fmt: str) -> dict:
    """The benchmark bag (module docstring); returns its numbers."""
    rng = np.random.default_rng(0)
    robot = load_robot(ROBOT)
    n_images = int(size_mb * 1e6 / (W * H))
    period = (n_images / CAMERA_HZ - REST_S) / (RESTS - 1)  # s per rest + move
    move_s = max(period - REST_S, 0.3)
    rests = robot.home + rng.uniform(-0.3, 0.3, (RESTS, robot.n))
    views = [_board_view(k, rng) for k in range(RESTS)]
    noise = [rng.integers(0, 255, (H, W), np.uint8) for _ in range(4)]
    t0 = 1_000 * NS
    starts = t0 + (np.arange(RESTS) * (REST_S + move_s) * NS).astype(np.int64)

    def q_at(t: int) -> tuple[np.ndarray, int | None]:
        k = int(np.clip(np.searchsorted(starts, t, side="right") - 1, 0, RESTS - 1))
        dt = (t - starts[k]) / NS
        if dt <= REST_S or k == RESTS - 1:
            return rests[k], k
        s = min((dt - REST_S) / move_s, 1.0)  # at constant speed (0.3 rad in under 40 s)
        q = rests[k] + (rests[k + 1] - rests[k]) * s
        # the camera sees the board while the arm is within 1 mrad of a rest, noise otherwise
        near = [j for j in (k, k + 1) if np.abs(q - rests[j]).max() < 1e-3]
        return q, near[0] if near else None

    end = int(starts[-1] + REST_S * NS) + NS // 2
    names = list(robot.joint_names)
    cam_t = t0 + (np.arange(int((end - t0) / NS * CAMERA_HZ)) * NS // CAMERA_HZ)
    joint_t = np.arange(t0 - NS // 2, end, NS // JOINT_HZ)
    written = 0
    with BagWriter(path, fmt) as w:
        ci = 0
        for t in joint_t:
            while ci < len(cam_t) and cam_t[ci] <= t:
                _, k = q_at(int(cam_t[ci]))
                w.image("/camera/image_raw", int(cam_t[ci]), "camera",
                        views[k] if k is not None else noise[ci % len(noise)])  # fmt: skip
                written += 1
                ci += 1
            w.joint_state("/joint_states", int(t), names, q_at(int(t))[0])
    return {"images": written, "joint_states": len(joint_t), "seconds": (end - t0) / NS}


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def measure(bag: Path, work: Path) -> tuple[float, float, int]:
    """Wall time (s), peak RSS (MB) and exit code of ``selfcal import --bag`` in a child."""
    (work / "board.toml").write_text(TARGET_TOML)
    out = work / "ds"
    if out.exists():
        shutil.rmtree(out)
    cmd = [sys.executable, "-m", "selfcal.cli.main", "import", "--bag", str(bag),
           "--image-topic", "cam0=/camera/image_raw", "--robot", ROBOT,
           "--target", str(work / "board.toml"), "--out", str(out), "--per-rest", "1",
           "--camera-model", "pinhole"]  # fmt: skip
    code, wall, peak_mb = run_child(cmd, stderr=work / "stderr.txt")
    for line in (work / "stderr.txt").read_text().splitlines():
        if code != 0 or "skipped" in line:
            print("  " + line.split("Warning: ", 1)[-1], file=sys.stderr)
    return wall, peak_mb, code


def main(argv: list[str] | None = None) -> int:
    p = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    p.add_argument("--size-mb", type=float, nargs="+", default=[300.0, 2000.0])
    p.add_argument("--format", default="ros1", choices=("ros1", "ros2", "mcap"))
    p.add_argument("--keep", default=None, help="write the bags here and keep them")
    args = p.parse_args(argv)
    base = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_ros_"))
    base.mkdir(parents=True, exist_ok=True)
    print(
        f"{'bag MB':>8} {'images':>7} {'write s':>8} {'import s':>9} {'peak RSS MB':>12} {'frames':>7}"
    )
    try:
        for mb in args.size_mb:
            bag = base / (f"b{int(mb)}.bag" if args.format == "ros1" else f"b{int(mb)}")
            if bag.exists():
                shutil.rmtree(bag) if bag.is_dir() else bag.unlink()
            t = time.perf_counter()
            info = write_bag(bag, mb, args.format)
            tw = time.perf_counter() - t
            wall, rss, code = measure(bag, base)
            frames = (
                "error" if code else str(len((base / "ds" / "joints.csv").read_text().split()) - 1)
            )
            print(f"{_size(bag) / 1e6:8.0f} {info['images']:7d} {tw:8.1f} {wall:9.1f} {rss:12.0f} "
                  f"{frames:>7}", flush=True)  # fmt: skip
            if not args.keep:
                shutil.rmtree(bag) if bag.is_dir() else bag.unlink()
    finally:
        if not args.keep:
            shutil.rmtree(base, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
