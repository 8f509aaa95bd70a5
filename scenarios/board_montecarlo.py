"""Monte Carlo of the known-board route (one camera + ChArUco) against its Cramer-Rao bound.

The truth is a scenario's (default ``scenarios/mono.toml``: one camera with the issue's lens,
k1 = -0.25, k2 = 0.1, p1 = 1e-3, p2 = -5e-4, principal point (+12, -8) px off centre): its
actual robot, planned postures (dithered per draw, read back at encoder resolution, as
:mod:`scenarios.montecarlo` does) and a ChArUco board (11 x 8 inner corners, 20 mm squares) lying
where the marker field would be. Every draw projects the board's corners with the true camera at
the true poses, adds Gaussian noise of ``pixel_sigma`` px and runs
:func:`calib.board_robot.calibrate_robot_with_board` (OpenCV's calibration as the start, the
two-stage fit, then the one-step refinement with joint corrections).

The bound is the Fisher information of that refinement's own problem evaluated at the truth
(camera, kinematics in the board frame, the read-back's prior; the board's points known): the
tool tip's RMS over the validation postures after the best rigid alignment (as
:mod:`calib.report` measures it, :func:`calib.estimation.joint_report.aligned_tool_rms_bound`)
and every free camera parameter. The achieved ratio is ``sqrt(mean over draws of rms^2) /
bound``.

``uv run python -m scenarios.board_montecarlo --draws 30`` prints the table row of
docs/cameras.md.
"""

from __future__ import annotations

import argparse
import functools
import tempfile
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.alignment import express_in_frame
from calib.board_robot import calibrate_robot_with_board
from calib.bundle_adjust import _Problem as _AdjustmentProblem
from calib.camera import CameraModel
from calib.estimation.joint_report import aligned_tool_rms_bound, encoder_sigma
from calib.estimation.kinematic_poses import KinematicPoses
from calib.estimation.residuals import GaussianPriorBlock
from calib.io.dataset import Dataset
from calib.io.truth import read_truth
from calib.kinematics import fk_tool
from calib.mcpc import MCPCModel, minimal_indices, nominal_mcpc
from calib.report import aligned_errors
from calib.robot_def import load_robot
from calib.solver import covariance
from calib.target import Charuco, Features
from calib.transforms import inv_pose, make_pose
from scenarios.montecarlo import _acquire

__all__ = ["BOARD", "BoardDraw", "board_pose", "board_views", "board_draw", "run_board_montecarlo"]

BOARD = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")
MONO = Path(__file__).resolve().with_name("mono.toml")


@dataclass(frozen=True)
class BoardDraw:
    """One draw: the tool tip's aligned RMS (mm) achieved and its bound, and per free camera
    parameter the error (estimate - truth) and its bound (px or unitless)."""

    tip_rms_mm: float
    bound_tip_mm: float
    camera_err: dict[str, float]
    camera_bound: dict[str, float]


def board_pose(truth, board: Charuco = BOARD) -> np.ndarray:
    """``T_world_board``: the board printed face up (board z down), centred on the marker
    field of ``truth`` (:class:`calib.io.truth.Truth`; world, m)."""
    centre = np.asarray(truth.marker_field["T_world_marker_m"])[:, :3, 3].mean(axis=0)
    _, pts = board.layout()
    size = pts.max(axis=0) + pts.min(axis=0)  # the corners' extent plus one square each side
    return make_pose(
        np.diag([1.0, -1.0, -1.0]), [centre[0] - size[0] / 2, centre[1] + size[1] / 2, 0.0]
    )


def board_views(
    truth,
    indices,
    camera: CameraModel,
    T_world_board: np.ndarray,
    sigma_px: float,
    seed: int,
    board: Charuco = BOARD,
) -> tuple[list[Features], np.ndarray]:
    """The board's corners seen by the left camera in the frames ``indices`` of ``truth``
    (true poses, ``camera`` the true model), in the image, plus Gaussian noise of ``sigma_px``
    px; and the frames' true joints (m, n) rad."""
    ids, pts = board.layout()
    rng = np.random.default_rng(seed)
    feats, q = [], []
    for i in indices:
        fr = truth.frame(int(i))
        assert fr is not None
        T = inv_pose(fr.T_world_cam_left) @ T_world_board
        Xc = pts @ T[:3, :3].T + T[:3, 3]
        uv = camera.project(Xc)
        ok = camera.in_image(uv, 2.0) & (Xc[:, 2] > 0)
        feats.append(Features(ids[ok], uv[ok] + rng.normal(0, sigma_px, (int(ok.sum()), 2))))
        q.append(fr.joints_rad)
    return feats, np.asarray(q)


def _bound(
    camera: CameraModel,
    model_board: MCPCModel,
    q_true: np.ndarray,
    feats: list[Features],
    sigma_px: float,
    joint_sigma: np.ndarray | None,
    q_valid: np.ndarray,
    T_cam_tip: np.ndarray,
) -> tuple[float, dict[str, float]]:
    """The tool tip's aligned-RMS bound (m) and the free camera parameters' bounds: the
    covariance of the board refinement's problem at the truth (every minimal parameter free)."""
    idx = minimal_indices(model_board.joint_types)
    m = len(q_true)
    poses = KinematicPoses(
        model_board, q_true, idx, np.zeros((0, 4, 4)), np.ones(m, bool),
        joint_corrections=joint_sigma is not None,
    )  # fmt: skip
    view = np.concatenate([np.full(len(f), i) for i, f in enumerate(feats)])
    ids, pidx = np.unique(np.concatenate([f.ids for f in feats]), return_inverse=True)
    uv = np.concatenate([f.uv for f in feats])
    extra = []
    if joint_sigma is not None:
        extra.append(GaussianPriorBlock("poses", poses.dq_cols, np.tile(sigma_px / joint_sigma, m)))
    x0 = np.concatenate([camera.free_values(), poses.initial_params()])
    prob = _AdjustmentProblem(
        camera, poses, view, pidx, uv, len(ids), x0=x0, extra=extra,
        fixed_points=BOARD.points(ids),
    )  # fmt: skip
    C = covariance(
        prob.problem, x0, ["intrinsics", ("poses", np.arange(poses.k))], sigma2=sigma_px**2
    )
    n_cam = camera.n_free
    cam = dict(zip(camera.free, np.sqrt(np.diag(C)[:n_cam]).tolist(), strict=True))

    @dataclass
    class _Cov:  # what aligned_tool_rms_bound reads
        model: MCPCModel
        covariance: np.ndarray

    tip = aligned_tool_rms_bound(_Cov(model_board, C[n_cam:, n_cam:]), q_valid, T_cam_tip)
    return tip, cam


def board_draw(seed: int, *, config: str | Path = MONO, pixel_sigma: float = 0.5) -> BoardDraw:
    """One noise draw (seed ``seed``: the corner noise and the dither of the postures)."""
    settings = {
        "poses": 30, "pixel_sigma": pixel_sigma, "seed": seed, "traj_seed": 1,
        "perturb_seed": 1, "dither": True, "config": str(config),
    }  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="selfcal-board-mc-") as d:
        s = _acquire(settings, Path(d) / "run")
        ds, truth = Dataset.open(Path(d) / "run"), read_truth(Path(d) / "run" / "truth.json")
    robot = load_robot(ds.info.robot_model)
    T_world_board = board_pose(truth)
    cam = s.camera.true_model()
    feats, q_true = board_views(truth, ds.indices, cam, T_world_board, pixel_sigma, seed + 7)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    js = encoder_sigma(robot)
    W, H = ds.info.resolution
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # identification notes
        res = calibrate_robot_with_board(
            BOARD, feats, np.radians(ds.joints_deg), nominal, W, H, free=s.camera.free,
            model=s.camera.model, joint_sigma=js,
        )  # fmt: skip
    qv = np.radians(ds.info.validation_joints_deg)
    true_board = express_in_frame(truth.true_model, inv_pose(T_world_board), like=nominal)
    tips_true = (fk_tool(true_board, qv) @ truth.T_cam_tip)[:, :3, 3]
    tips = (fk_tool(res.model, qv) @ truth.T_cam_tip)[:, :3, 3]
    rms = aligned_errors(tips, tips_true)["rms"]
    b_tip, b_cam = _bound(cam, true_board, q_true, feats, pixel_sigma, js, qv, truth.T_cam_tip)
    true_vals = dict(zip(cam.names, cam.values().tolist(), strict=True))
    est_vals = dict(zip(res.camera.names, res.camera.values().tolist(), strict=True))
    err = {n: est_vals[n] - true_vals[n] for n in cam.free}
    return BoardDraw(rms, 1000.0 * b_tip, err, b_cam)


def run_board_montecarlo(draws: int, *, first_seed: int = 1, jobs: int = 2, **kw) -> dict:
    """``draws`` draws (``jobs`` processes): the tool-tip ratio ``sqrt(mean rms^2) / median
    bound`` and per camera parameter ``sqrt(mean (err / bound)^2)``."""
    seeds = [first_seed + k for k in range(draws)]
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        rows = list(pool.map(functools.partial(board_draw, **kw), seeds))
    bound = float(np.median([r.bound_tip_mm for r in rows]))
    tip = float(np.sqrt(np.mean([r.tip_rms_mm**2 for r in rows])))
    names = list(rows[0].camera_err)
    cam = {
        n: float(np.sqrt(np.mean([(r.camera_err[n] / r.camera_bound[n]) ** 2 for r in rows])))
        for n in names
    }
    return {"draws": draws, "tip_rms_mm": tip, "bound_tip_mm": bound, "tip_ratio": tip / bound,
            "camera_ratio": cam}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument("--config", default=str(MONO))
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    r = run_board_montecarlo(a.draws, config=a.config, jobs=a.jobs)
    cams = ", ".join(f"{n} {v:.2f}" for n, v in r["camera_ratio"].items())
    print(
        f"| one camera + ChArUco | {r['draws']} | {r['tip_rms_mm']:.4f} mm | "
        f"{r['bound_tip_mm']:.4f} mm | {r['tip_ratio']:.3f} | {cams} |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
