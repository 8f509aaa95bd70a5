"""The pose route's hand-eye against OpenCV 4.x's seven methods, judged on held-out reprojection.

Every case is a training set and a held-out set of images of a board with the robot's flange
poses (eye-in-hand or eye-to-hand). Ours: :func:`selfcal.calibration.handeye.calibrate.calibrate_hand_eye`
on the training frames: its linear start (the camera stage's camera, Park's rotation), its
nominal (camera stage's camera held, hand-eye and board mount on corner reprojection), the fit
with the camera refined too, and its answer (the nominal or the refined fit, as the camera's
cross-validation chose), with the flange poses' noise ``"auto"``; the fit with the camera
refined and the poses exact and always corrected (:mod:`selfcal.calibration.handeye.eiv`); how
often the camera was held, and how often the one-standard-error rule would have held it
(:func:`one_standard_error_holds`, reported, not used). A second table: the fits' errors against
the synthetic truth. OpenCV's (:mod:`selfcal.benchmarks.handeye.opencv4`,
in its own OpenCV 4.x environment): ``cv2.calibrateCamera`` on the same training frames and
corners (the same distortion model: k1, k2, p1, p2, ``CALIB_FIX_K3``), then each of
``cv2.calibrateHandEye``'s five methods (the board mount: the chordal mean over the training
frames of the board pose each frame implies, and the mean translation) and
``cv2.calibrateRobotWorldHandEye``'s two (which return the board mount). Every model predicts
each held-out corner from the held-out flange pose alone; the table gives the RMS (px) over
those corners.

Data: (a) synthetic: a 7 x 5 chessboard (30 mm) seen from 0.4-0.6 m by a 1280 x 960 camera
with distortion, random hand-eye and board mount, 12 training and 20 held-out frames, corner
noise 0.2 or 1 px, and once 0.5 mm / 0.05 deg per axis of noise on the reported flange poses
(as a real arm's); five seeds each (``--seeds``), both setups. (b) real: ROS-Industrial's ical-charuco
(tests/data/real/ical-charuco; eye-to-hand, its README's split: images 0, 3, 6, 9, 12, 15 held
out).

Run: ``uv run python -m selfcal.benchmarks.handeye.poses [--seeds N] [--write-docs]``
(rewrites the table in docs/handeye.md between its markers).
"""

from __future__ import annotations

import json
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.doc_blocks import ROOT, write_block
from selfcal.benchmarks.handeye.joints import run_opencv4
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.handeye.calibrate import (
    CameraChoice,
    calibrate_hand_eye,
    chain_motions,
    predict_corners,
)
from selfcal.calibration.handeye.eiv import EXACT
from selfcal.camera import CameraModel, camera_model
from selfcal.errors import InputError, SelfCalError
from selfcal.io.atomic import write_text_atomic
from selfcal.io.images import read_gray_image
from selfcal.io.poses.files import read_poses
from selfcal.io.target_toml import load_target
from selfcal.target.base import Features
from selfcal.target.boards import Board, Chessboard
from selfcal.transforms import inv_pose, make_pose

__all__ = ["Split", "synthetic_split", "ical_split", "one_standard_error_holds", "run", "table",
           "main"]  # fmt: skip

DOC = ROOT / "docs" / "handeye.md"
ICAL = ROOT / "tests" / "data" / "real" / "ical-charuco"
ICAL_HELD_OUT = (0, 3, 6, 9, 12, 15)
OURS = ("calibrated", "nominal", "camera refined", "linear start", "poses exact",
        "poses corrected")  # fmt: skip
"""Our models: the answer ``calibrate`` writes (the pose noise and the camera ``"auto"``), its
nominal (the camera stage's camera held), the fit with the camera refined (the answer before
the camera was chosen), its linear start, and the fit with the camera refined and the flange
poses taken as exact and with their corrections always (:mod:`selfcal.calibration.handeye.eiv`)."""
MODES = {"poses exact": EXACT, "poses corrected": "estimate"}
OPENCV = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS", "SHAH", "LI")
FREE = ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2")
"""Ours frees these (the opencv model's default); OpenCV's calibrateCamera the same (fixed k3)."""
CV_FLAGS = ["CALIB_FIX_K3"]
NOISE = ((0.2, 0.0, 0.0), (1.0, 0.0, 0.0), (0.2, 0.5, 0.05))
"""Synthetic cases: corner noise (px), flange pose noise per axis (mm, deg)."""
BOARD = Chessboard((7, 5), 0.03)
CAMERA = camera_model("opencv", fx=900.0, mu=1.002, cx=645.0, cy=478.0, width=1280, height=960,
                      coeffs={"k1": -0.12, "k2": 0.08})  # fmt: skip


@dataclass(frozen=True)
class Split:
    """One case: ``setup``, the ``board``, training and held-out ``features`` (one per frame,
    px) and reported flange poses ``T_base_flange`` (n, 4, 4) m, the image size."""

    name: str
    setup: str
    board: Board
    train: list[Features]
    train_flange: np.ndarray
    held: list[Features]
    held_flange: np.ndarray
    width: int
    height: int
    X_true: np.ndarray | None = None
    B_true: np.ndarray | None = None


def _look_at(eye: np.ndarray, target: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """T_world_cam of a camera at ``eye`` looking at ``target`` with a random roll."""
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, rng.normal(size=3))
    x /= np.linalg.norm(x)
    return make_pose(np.stack([x, np.cross(z, x), z], axis=1), eye)


def synthetic_split(setup: str, pixel_px: float, pose_mm: float, pose_deg: float, seed: int,
                    n_train: int = 12, n_held: int = 20) -> Split:  # fmt: skip
    """A synthetic case (module docstring): truth drawn from ``seed``, corners with Gaussian
    noise ``pixel_px`` per coordinate, the reported flange poses with ``pose_mm`` / ``pose_deg``
    per axis (the images are of the true poses)."""
    rng = np.random.default_rng(seed)
    X = make_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-0.1, 0.1, 3))
    B = make_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-0.2, 0.2, 3))
    if setup == "eye-to-hand":
        X[:3, 3] += [0.0, 1.0, 0.5]  # the static camera in the base frame
    else:
        B[:3, 3] += [0.6, 0.0, 0.0]  # the static board in the base frame
    ids = np.arange(BOARD.n_features)
    P = BOARD.points(ids)
    centre = P.mean(axis=0)
    n = n_train + n_held
    flange, feats = np.empty((n, 4, 4)), []
    for k in range(n):  # a camera pose around the board's normal, then the flange that gives it
        eye = centre + rng.uniform(0.4, 0.6) * np.r_[rng.uniform(-0.5, 0.5, 2), -1.0] / 1.118
        T_cam_board = inv_pose(_look_at(eye, centre, rng))
        A = X @ T_cam_board @ inv_pose(B)  # T_cam_board = X^-1 A B
        flange[k] = A if setup == "eye-to-hand" else inv_pose(A)
        uv = CAMERA.project(P @ T_cam_board[:3, :3].T + T_cam_board[:3, 3])
        feats.append(Features(ids, uv + rng.normal(0.0, pixel_px, uv.shape)))
    noise = np.hstack([np.radians(pose_deg) * rng.normal(size=(n, 3)),
                       1e-3 * pose_mm * rng.normal(size=(n, 3))])  # fmt: skip
    reported = flange @ make_pose(Rotation.from_rotvec(noise[:, :3]).as_matrix(), noise[:, 3:])
    name = f"{setup}, {pixel_px:g} px" + (
        f", poses {pose_mm:g} mm / {pose_deg:g}°" if pose_mm else ""
    )
    return Split(name, setup, BOARD, feats[:n_train], reported[:n_train], feats[n_train:],
                 reported[n_train:], CAMERA.width, CAMERA.height, X, B)  # fmt: skip


def ical_split() -> Split | None:
    """ical-charuco on its README's split (eye-to-hand); None when the set is not there."""
    cal_data = ICAL / "examples" / "data" / "test_set_charuco" / "cal_data.yaml"
    if not cal_data.is_file():
        return None
    board = load_target(ICAL / "inputs" / "target.toml")
    assert isinstance(board, Board)
    rows = read_poses(cal_data)
    assert rows.images is not None
    feats, held, shape = [], [], (0, 0)
    for path in rows.images:
        img = read_gray_image(path)
        if img is None:
            raise InputError(f"{path}: the image is missing or unreadable",
                             fix="copy the real set into tests/data/real/ical-charuco again")  # fmt: skip
        shape = img.shape
        feats.append(board.detect(img))
        held.append(int(Path(path).stem) in ICAL_HELD_OUT)
    h = np.array(held)
    keep = lambda m: [f for f, k in zip(feats, m, strict=True) if k]  # noqa: E731
    return Split("ical-charuco (real), eye-to-hand", "eye-to-hand", board, keep(~h),
                 rows.T_base_flange[~h], keep(h), rows.T_base_flange[h], shape[1], shape[0])  # fmt: skip


def _rows(board: Board, feats: list[Features], frames: np.ndarray):
    """Per-corner view index, board points (m) and pixels of ``frames``."""
    fs = [feats[i] for i in frames.tolist()]
    view = np.concatenate([np.full(len(f), k) for k, f in enumerate(fs)])
    return (
        view,
        board.points(np.concatenate([f.ids for f in fs])),
        np.concatenate([f.uv for f in fs]),
    )


def _rms(pred: np.ndarray, uv: np.ndarray) -> float:
    """RMS (px) of ``pred - uv``; inf when a corner is behind the camera (NaN)."""
    e = np.sum((pred - uv) ** 2, axis=1)
    return float(np.sqrt(np.mean(e))) if np.isfinite(e).all() else float("inf")


def _truth_errors(s: Split, X: np.ndarray, B: np.ndarray) -> list[float]:
    """The hand-eye's and the board mount's rotation (deg) and translation (mm) errors against
    the synthetic truth (empty for a real set)."""
    if s.X_true is None or s.B_true is None:
        return []
    out = []
    for T, T0 in ((X, s.X_true), (B, s.B_true)):
        D = inv_pose(T0) @ T
        out += [float(np.degrees(Rotation.from_matrix(D[:3, :3]).magnitude())),
                float(1e3 * np.linalg.norm(T[:3, 3] - T0[:3, 3]))]  # fmt: skip
    return out


def _ours(s: Split, held: np.ndarray) -> tuple[dict, np.ndarray]:
    """Our models' held-out RMS (px), their errors against the truth (``truth``: model -> X deg,
    X mm, B deg, B mm; synthetic only), the cross-validation's choice (``corrected``: 1 when the
    answer uses the corrections) and the training frames they used."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = lambda noise, camera: calibrate_hand_eye(  # noqa: E731
            s.board, s.train, s.train_flange, s.setup, s.width, s.height, model="opencv",
            free=FREE, pose_noise=noise, camera=camera)  # fmt: skip
        cal = fit("auto", "auto")
        if cal.refined is None:  # pragma: no cover - camera="auto" refines it
            raise SystemExit("the hand-eye fit with camera='auto' gave no refined camera")
        refined = cal.refined
        others = {k: fit(m, "refined").calibrated for k, m in MODES.items()}
    view, pts, uv = _rows(s.board, s.held, np.flatnonzero(held))
    A = chain_motions(s.setup, s.held_flange[held])
    models: dict[str, tuple[CameraModel, np.ndarray, np.ndarray]] = {
        "calibrated": (cal.calibrated.camera, cal.calibrated.X, cal.calibrated.B),
        "nominal": (cal.nominal.camera, cal.nominal.X, cal.nominal.B),
        "camera refined": (refined.camera, refined.X, refined.B),
        "linear start": (cal.camera_stage.camera, cal.X0, cal.B0),
        **{k: (f.camera, f.X, f.B) for k, f in others.items()},
    }
    out: dict = {k: _rms(predict_corners(c, X, B, A, view, pts), uv)
                 for k, (c, X, B) in models.items()}  # fmt: skip
    out["truth"] = {k: _truth_errors(s, X, B) for k, (_, X, B) in models.items()}
    out["corrected"] = int(cal.pose_choice is not None and cal.pose_choice.eiv)
    ch = cal.camera_choice
    assert ch is not None and cal.refined is not None  # camera "auto"
    out["camera held"] = int(not cal.camera_refined)
    out["one-SE held"] = int(one_standard_error_holds(ch))
    out["camera cv"] = (ch.held_px, ch.refined_px)
    return out, cal.used


def one_standard_error_holds(ch: CameraChoice) -> bool:
    """What the one-standard-error rule (Hastie, Tibshirani and Friedman, The Elements of
    Statistical Learning, 7.10) would choose for the camera from ``ch``'s folds: the simpler
    model (the camera held) unless the other's cross-validation error (the mean over the folds
    of each fold's mean squared error, px^2) plus its standard error (the folds' standard
    deviation / sqrt(folds)) is below the simpler model's. Reported beside the route's own
    rule (:func:`selfcal.calibration.handeye.fit.predict_better`), not used by it."""
    h, r = np.square(ch.held_fold_px), np.square(ch.refined_fold_px)
    if not np.isfinite(r).all():
        return True
    if not np.isfinite(h).all():
        return False
    return bool(h.mean() <= r.mean() + r.std(ddof=1) / np.sqrt(len(r)))


def _request(s: Split, used: np.ndarray, held: np.ndarray) -> dict:
    """The OpenCV side's case (:mod:`selfcal.benchmarks.handeye.opencv4`)."""
    tr = np.flatnonzero(used)
    obj = lambda fs, fr: [s.board.points(fs[i].ids).tolist() for i in fr]  # noqa: E731
    return {"size": [s.width, s.height], "flags": CV_FLAGS,
            "train": {"object": obj(s.train, tr), "image": [s.train[i].uv.tolist() for i in tr],
                      "A": chain_motions(s.setup, s.train_flange[tr]).tolist()},
            "held": {"object": obj(s.held, np.flatnonzero(held)),
                     "A": chain_motions(s.setup, s.held_flange[held]).tolist()}}  # fmt: skip


def opencv4(cases: list[dict], workdir: Path) -> dict:
    """OpenCV 4.x's answers to ``cases`` (see :mod:`selfcal.benchmarks.handeye.opencv4`); raises
    :class:`selfcal.errors.SelfCalError` saying why when its environment does not run."""
    src, dst = workdir / "in.json", workdir / "out.json"
    write_text_atomic(src, json.dumps({"cases": cases}))
    why = run_opencv4(src, dst)
    if why is not None:
        raise SelfCalError(why, fix="install uv; OpenCV 4.x comes from the package registry")
    return json.loads(dst.read_text())


def run(splits: list[Split]) -> tuple[list[dict], str]:
    """Per split ``{"name", "corners" (held out), "opencv_camera_rms" (calibrateCamera's, px),
    each of :data:`OURS` and :data:`OPENCV`: held-out RMS px}`` (NaN: OpenCV gave no answer;
    inf: corners behind the camera) and OpenCV's version."""
    rows, cases = [], []
    for s in splits:
        held = np.array([len(f) >= s.board.min_features for f in s.held])
        ours, used = _ours(s, held)
        rows.append({"name": s.name, "corners": int(sum(len(s.held[i]) for i in np.flatnonzero(held))),
                     **ours})  # fmt: skip
        cases.append((s, held, _request(s, used, held)))
    with tempfile.TemporaryDirectory(prefix="selfcal-handeye-poses-") as d:
        out = opencv4([c for *_, c in cases], Path(d))
    for row, (s, held, _), got in zip(rows, cases, out["cases"], strict=True):
        _, _, uv = _rows(s.board, s.held, np.flatnonzero(held))
        row["opencv_camera_rms"] = got["camera"]["rms"]
        for m in OPENCV:
            r = got["methods"][m]
            row[m] = float("nan") if "error" in r else _rms(np.concatenate(
                [np.array(p, float).reshape(-1, 2) for p in r["pred"]]), uv)  # fmt: skip
    return rows, f"OpenCV {out['version']}"


def _best(g: dict) -> str:
    """The OpenCV method with the lowest mean held-out RMS of the group ``g``."""
    return min(OPENCV, key=lambda m: g[m] if np.isfinite(g[m]) else np.inf)


def _group(rows: list[dict]) -> list[dict]:
    """Rows of one name (seeds) merged: the mean of each method's RMS, and in how many seeds
    ours (calibrated) is at most the best OpenCV method (the lowest mean: the best of seven
    per seed would hold ours to the luckiest method of each seed)."""
    out: dict[str, dict] = {}
    for r in rows:
        out.setdefault(r["name"], {"name": r["name"], "all": []})["all"].append(r)
    for g in out.values():
        for m in OURS + OPENCV:
            g[m] = float(np.mean([r[m] for r in g["all"]]))
        g["n"], g["best"] = len(g["all"]), _best(g)
        g["wins"] = sum(int(r["calibrated"] <= r[g["best"]]) for r in g["all"])
        g["corrected"] = sum(r["corrected"] for r in g["all"])
        g["camera held"] = sum(r["camera held"] for r in g["all"])
        g["one-SE held"] = sum(r["one-SE held"] for r in g["all"])
        g["truth"] = {m: np.sqrt(np.mean(np.square([r["truth"][m] for r in g["all"]]), axis=0))
                      for m in OURS if g["all"][0]["truth"][m]}  # fmt: skip
    return list(out.values())


TRUTH_MODELS = ("poses exact", "poses corrected", "camera refined", "calibrated")
"""The models of the truth table (:func:`table`)."""


def table(rows: list[dict], version: str) -> str:
    """The markdown table of :func:`run`'s rows (seeds merged by :func:`_group`)."""
    fmt = lambda v: "no answer" if np.isnan(v) else "behind" if np.isinf(v) else f"{v:.3f}"  # noqa: E731
    head = ["case", "seeds", *(f"ours: {m}" for m in OURS), *OPENCV, "ours ≤ best OpenCV (seeds)",
            "answer corrected (seeds)", "camera held (seeds)", "1-SE rule: held (seeds)"]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    groups = _group(rows)
    for g in groups:
        best = g["best"]
        cells = [fmt(g[m]) for m in OURS]
        cells += [f"**{fmt(g[m])}**" if m == best else fmt(g[m]) for m in OPENCV]
        lines.append(f"| {g['name']} | {g['n']} | " + " | ".join(cells)
                     + f" | {g['wins']} of {g['n']} | {g['corrected']} of {g['n']} | "
                     f"{g['camera held']} of {g['n']} | {g['one-SE held']} of {g['n']} |")  # fmt: skip
    lines += ["", f"(Held-out RMS in px, the mean over the seeds; bold: the best OpenCV method; "
              f"{version}; 'behind': the model puts held-out corners behind the camera.)"]  # fmt: skip
    short = {"poses exact": "exact", "poses corrected": "corrected", "camera refined": "refined",
             "calibrated": "answer"}  # fmt: skip
    what = ("hand-eye rotation (deg)", "hand-eye translation (mm)", "board mount rotation (deg)",
            "board mount translation (mm)")  # fmt: skip
    head = ["case"] + [f"{w}: {short[m]}" for w in what for m in TRUTH_MODELS]
    lines += ["", "| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for g in groups:
        if g["truth"]:
            cells = [f"{g['truth'][m][i]:.3f}" for i in range(4) for m in TRUTH_MODELS]
            lines.append(f"| {g['name']} | " + " | ".join(cells) + " |")
    lines += ["", "(Errors against the synthetic truth, RMS over the seeds: the camera refined "
              "with the flange poses taken as exact, always corrected and as `auto` chose, and "
              "calibrate's answer.)"]  # fmt: skip
    return "\n".join(lines)


def splits(seeds: int) -> list[Split]:
    """The synthetic cases (``seeds`` each, both setups) and ical-charuco when it is there."""
    out = [synthetic_split(setup, px, mm, deg, seed)
           for setup in ("eye-in-hand", "eye-to-hand") for px, mm, deg in NOISE
           for seed in range(1, seeds + 1)]  # fmt: skip
    real = ical_split()
    return out + ([real] if real is not None else [])


def main(argv: list[str] | None = None) -> int:
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5, help="synthetic seeds per case (5)")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the table in docs/handeye.md")  # fmt: skip
    a = ap.parse_args(argv)
    rows, version = run(splits(a.seeds))
    text = table(rows, version)
    print(text)
    if a.write_docs:
        write_block(DOC, text, "benchmark_handeye_poses")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
