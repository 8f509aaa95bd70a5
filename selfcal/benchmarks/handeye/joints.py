"""The hand-eye against OpenCV 4.x's ``cv2.calibrateRobotWorldHandEye`` on the same board data.

Data: a board projected into a field scenario (:mod:`selfcal.benchmarks.board.views`;
``scenarios/mono.toml``: one camera with the issue's lens, the ChArUco board where the field lies, 30 postures, 0.5 px corner
noise, read-back at encoder resolution), once with the scenario's perturbed kinematics (±1 mm,
±0.5 deg) and once with exact kinematics (the robot is its nominal model, so OpenCV's
assumption of known kinematics holds). Ours: :func:`selfcal.calibration.board.robot.calibrate_robot_with_board`
(camera, hand-eye, board pose and kinematics). OpenCV's: the board poses of OpenCV's camera
calibration (``cv2.calibrateCamera`` on the views that show enough of the board, the start of
ours) and the nominal flange poses at those views' joint readings into ``cv2.calibrateRobotWorldHandEye`` (in its own environment,
:mod:`selfcal.benchmarks.handeye.opencv4`). Both predict the camera pose in the board frame at 20
held-out postures; the table gives the RMS position (mm) and rotation (deg) errors against the
truth.

Run: ``uv run python -m selfcal.benchmarks.handeye [--write-docs]`` (rewrites the table in
docs/cameras.md between its markers).
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.board.views import BOARD, MONO, board_pose, board_views
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.robot import calibrate_robot_with_board
from selfcal.estimation.joint_report import encoder_sigma
from selfcal.io.atomic import write_text_atomic
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.studies.montecarlo.run import acquire_draw
from selfcal.transforms import inv_pose

__all__ = ["run", "main", "run_opencv4"]

DOC = Path(__file__).resolve().parents[3] / "docs" / "cameras.md"
BEGIN, END = "<!-- benchmark_handeye begin -->", "<!-- benchmark_handeye end -->"
OPENCV4_CMD = ["uv", "run", "--no-project", "--python", "3.11"]
OPENCV4_CMD += ["--with", "opencv-python-headless<5", "--with", "numpy", "python"]


def _errors(T: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """RMS position (mm) and rotation (deg) errors of poses (k, 4, 4) against the truth."""
    dt = np.linalg.norm(T[:, :3, 3] - T_true[:, :3, 3], axis=1)
    dR = Rotation.from_matrix(np.swapaxes(T[:, :3, :3], 1, 2) @ T_true[:, :3, :3]).magnitude()
    return float(np.sqrt(np.mean(dt**2)) * 1e3), float(np.degrees(np.sqrt(np.mean(dR**2))))


def run_opencv4(src: Path, dst: Path) -> str | None:
    """Run :mod:`selfcal.benchmarks.handeye.opencv4` on ``src`` into ``dst`` in its OpenCV 4.x
    environment; None when it ran, else why it did not."""
    if shutil.which("uv") is None:
        return "uv not found"
    script = Path(__file__).with_name("opencv4.py")
    try:
        subprocess.run([*OPENCV4_CMD, str(script), str(src), str(dst)], check=True,
                       capture_output=True, text=True, timeout=1800)  # fmt: skip
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired, OSError) as exc:
        err = getattr(exc, "stderr", "") or str(exc)
        return f"OpenCV 4 did not run: {err.strip().splitlines()[-1:]}"
    return None


def _opencv4(T_cam_board: np.ndarray, T_flange_base: np.ndarray, workdir: Path):
    """``(T_board_base, T_cam_flange, version)`` from OpenCV 4.x, or ``(None, None, why)``."""
    src, dst = workdir / "in.npz", workdir / "out.npz"
    np.savez(src, T_cam_board=T_cam_board, T_flange_base=T_flange_base)
    why = run_opencv4(src, dst)
    if why is not None:
        return None, None, why
    with np.load(dst) as out:
        return out["T_board_base"], out["T_cam_flange"], f"OpenCV {out['version']}"


def _case(perturbed: bool, workdir: Path, seed: int = 1) -> dict:
    settings = {"poses": 30, "pixel_sigma": 0.5, "seed": seed, "traj_seed": 1,
                "perturb_seed": 1, "dither": True, "config": str(MONO)}  # fmt: skip
    root = workdir / f"run{int(perturbed)}"
    from selfcal.config.scenario import load_scenario

    if not perturbed:  # the robot is its nominal model
        cfg = workdir / "exact.toml"
        write_text_atomic(
            cfg, MONO.read_text() + "\n[perturbation]\ntranslation_mm = 0.0\nrotation_deg = 0.0\n"
        )
        settings["config"] = str(cfg)
    s = load_scenario(str(settings["config"]))
    acquire_draw(settings, root)
    ds, truth = Dataset.open(root), read_truth(root / "truth.json")
    robot = load_robot(ds.info.robot_model)
    T_world_board = board_pose(truth)
    cam = s.camera.true_model()
    feats, _ = board_views(truth, ds.indices, cam, T_world_board, 0.5, seed + 7)
    q = np.radians(ds.joints_deg)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    W, H = ds.info.resolution
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ours = calibrate_robot_with_board(BOARD, feats, q, nominal, W, H, free=s.camera.free,
                                          model=s.camera.model, joint_sigma=encoder_sigma(robot))  # fmt: skip
    flange = nominal_mcpc(robot)  # tool = the flange
    used = ours.board.used  # the views showing enough of the board (OpenCV's calibration's)
    T_cam_board = ours.board.opencv.T_cam_board
    qv = np.radians(ds.info.validation_joints_deg)
    T_true = inv_pose(T_world_board) @ fk_tool(truth.true_model, qv)  # board <- camera
    B, C, version = _opencv4(T_cam_board, inv_pose(fk_tool(flange, q[used])), workdir)
    row = {"case": "perturbed kinematics (±1 mm, ±0.5°)" if perturbed else "exact kinematics",
           "ours": _errors(fk_tool(ours.model, qv), T_true), "version": version}  # fmt: skip
    if B is not None:
        T_cv = B[None] @ fk_tool(flange, qv) @ inv_pose(C)[None]
        row["opencv"] = _errors(T_cv, T_true)
    return row


def run() -> list[dict]:
    with tempfile.TemporaryDirectory(prefix="selfcal-handeye-") as d:
        return [_case(False, Path(d)), _case(True, Path(d))]


def table(rows: list[dict]) -> str:
    lines = ["| kinematics | ours: position / rotation RMS | OpenCV `calibrateRobotWorldHandEye` |",
             "|---|---|---|"]  # fmt: skip
    for r in rows:
        cv = r.get("opencv")
        cv_s = f"{cv[0]:.3f} mm / {cv[1]:.4f}°" if cv else r["version"]
        lines.append(f"| {r['case']} | {r['ours'][0]:.3f} mm / {r['ours'][1]:.4f}° | {cv_s} |")
    lines.append("")
    lines.append(
        f"({rows[0]['version']}; camera poses in the board frame at 20 held-out postures.)"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(
        Path(__file__).with_name("__main__.py"), description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--write-docs", action="store_true")
    a = ap.parse_args(argv)
    rows = run()
    text = table(rows)
    print(text)
    if a.write_docs:
        doc = DOC.read_text()
        i, j = doc.index(BEGIN) + len(BEGIN), doc.index(END)
        write_text_atomic(DOC, doc[:i] + "\n" + text + "\n" + doc[j:])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
