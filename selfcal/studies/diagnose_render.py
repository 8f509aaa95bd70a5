"""Diagnose the rendered path: detected marker corners against their analytic projection.

Renders the scenario's planned postures with the simulated (actual) robot, detects the markers
and compares every detected corner with the projection of the field's true corner through the
true camera pose (MuJoCo's ``cam_xpos/cam_xmat``, OpenCV convention) and the true intrinsics.
Offsets (detected - analytic, px) are summarised per image region, per marker size in pixels,
per viewing angle and per corner index, for each corner refinement method asked for. Also checks
the camera poses MuJoCo renders from against the actual MCPC chain at the true joint angles, and
the reported (quantised) joint angles against the true ones.

``selfcal diagnose render [scenario.toml]`` or ``python -m selfcal.studies.diagnose_render``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.console.usage import module_parser

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = [
    "CornerOffsets",
    "measure",
    "summarise",
    "format_table",
    "plot",
    "main",
    "figure_path",
    "register",
]

SIZE_BINS_PX = (0.0, 25.0, 35.0, 50.0, np.inf)
ANGLE_BINS_DEG = (0.0, 30.0, 45.0, 55.0, 65.0, 90.0)


@dataclass(frozen=True)
class CornerOffsets:
    """One row per detected corner: offset ``d`` (n, 2) px (detected - analytic), analytic
    position ``uv`` (n, 2) px, marker side ``size_px`` (n,), viewing angle ``angle_deg`` (n,)
    (marker normal vs direction to the camera), ``corner`` (n,) index 0-3, ``marker`` (n,) id,
    ``image`` (n,) image index, ``sigma`` (n,) the detector's own noise estimate of the corner
    (px per coordinate, NaN if it gives none); ``pose_err_m`` the largest camera-position
    difference between MuJoCo and the actual chain (m), ``joint_quant_rad`` the largest
    |reported - true| angle, ``joint_err`` (m, n) reported - true per posture and joint and
    ``joint_step`` (n,) one count of the robot file's ``counts_per_deg`` (rad), ``joint_sigma``
    (n,) the read-back noise its encoder table gives (rad; inf without one)."""

    d: np.ndarray
    uv: np.ndarray
    size_px: np.ndarray
    angle_deg: np.ndarray
    corner: np.ndarray
    marker: np.ndarray
    image: np.ndarray
    sigma: np.ndarray
    pose_err_m: float
    joint_quant_rad: float
    joint_err: np.ndarray
    joint_step: np.ndarray
    joint_sigma: np.ndarray
    intrinsics_err_px: float

    def scale_error(self) -> float:
        """Relative marker-size error: least-squares radial scale of the detected corners about
        each detection's analytic centre (0 when the rendered and the field file's sizes agree;
        the corners' order is checked by the offsets themselves)."""
        c = self.uv.reshape(-1, 4, 2)
        r = (c - c.mean(axis=1, keepdims=True)).reshape(-1, 2)
        return float(np.einsum("ij,ij->", self.d, r) / np.einsum("ij,ij->", r, r))

    def noise_check(self) -> tuple[float, float]:
        """(achieved, predicted) per-coordinate corner RMS (px): the offsets against the
        detector's own noise estimate (:func:`selfcal.target.aruco_detect.detect_markers_noise`),
        over the corners that have one."""
        ok = np.isfinite(self.sigma)
        if not ok.any():
            return float("nan"), float("nan")
        return float(np.sqrt(np.mean(self.d[ok] ** 2))), float(
            np.sqrt(np.mean(self.sigma[ok] ** 2))
        )


def measure(
    config: str | Path | None = None,
    refine: tuple[str, ...] = ("lines",),
    max_poses: int | None = None,
    msaa: int | None = None,
    image_sigma: float = 0.0,
) -> dict[str, CornerOffsets]:
    """Render the scenario's planned postures (noise-free, or with ``image_sigma`` grey levels of
    the simulator's image noise, ``selfcal.sim.render.noise_field``) and measure, per refinement
    method in
    ``refine`` (see :data:`selfcal.target.aruco_detect.REFINE_METHODS`; suffix ``-unscreened``:
    keep occluded and oblique markers and refine the lines once, the detector before issue #14),
    every detected corner's offset from its analytic projection. ``max_poses`` limits the postures (None: all); ``msaa`` sets the renderer's multisample count (None: the
    scene's, 4)."""
    from selfcal.acquisition.backends import make_sim_robot, plan_dataset
    from selfcal.acquisition.simulator_setup import sim_setup
    from selfcal.camera import project
    from selfcal.config.scenario import load_scenario
    from selfcal.kinematics.forward import fk_tool
    from selfcal.sim.mj_camera import intrinsics_from_model
    from selfcal.sim.robot_mjcf import CAMERA_NAMES
    from selfcal.target.aruco_detect import detect_markers_noise
    from selfcal.transforms import inv_pose

    s = load_scenario(
        config, overrides={"noise": {"image_sigma": float(image_sigma), "render": True}}
    )
    setup = sim_setup(s)
    info = plan_dataset(s, setup)
    q_deg = np.asarray(info.planned_joints_deg)[:max_poses]
    fld = setup.marker_field()
    corners_w = fld.corners_world()
    normals = fld.T_world_marker[:, :3, 2]
    rows: dict[str, list] = {m: [] for m in refine}
    pose_err, quant, jerr = 0.0, 0.0, []
    with make_sim_robot(s, setup) as robot:
        if msaa is not None:
            robot.mj_model.vis.quality.offsamples = int(msaa)
        cams = (robot.rig.intrinsics, robot.rig.right)
        intr_err = 0.0
        for name, cam in zip(CAMERA_NAMES, cams, strict=True):
            got = intrinsics_from_model(robot.mj_model, name)
            intr_err = max(
                intr_err,
                *(abs(getattr(got, a) - getattr(cam, a)) for a in ("fx", "fy", "cx", "cy")),
            )
        for i, q in enumerate(q_deg):
            robot.move_to(q)
            fr = robot.truth_frame()
            T_chain = fk_tool(setup.actual, fr["joints_rad"][None])[0]
            pose_err = max(
                pose_err, float(np.abs(T_chain[:3, 3] - fr["T_world_cam_left"][:3, 3]).max())
            )
            jerr.append(np.radians(robot.joints()) - fr["joints_rad"])
            quant = max(quant, float(np.abs(jerr[-1]).max()))
            pair = robot.capture()
            for c, (img, key, intr) in enumerate(
                zip(
                    (pair.left, pair.right),
                    ("T_world_cam_left", "T_world_cam_right"),
                    cams,
                    strict=True,
                )
            ):
                T = np.asarray(fr[key])
                uv = project(intr, inv_pose(T), corners_w)  # (K, 4, 2)
                to_cam = T[:3, 3][None] - corners_w.mean(axis=1)
                cosang = np.einsum("kj,kj->k", to_cam, normals) / np.linalg.norm(to_cam, axis=1)
                ang = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
                for m in refine:
                    screen = not m.endswith("-unscreened")
                    method = m.removesuffix("-unscreened")
                    found, noise = detect_markers_noise(
                        img, fld.dictionary, method, screen=screen, passes=None if screen else 1
                    )
                    for mid, det in found.items():
                        k = fld.index_of(mid)
                        side = np.linalg.norm(uv[k] - np.roll(uv[k], -1, axis=0), axis=1).mean()
                        for j in range(4):
                            rows[m].append(
                                (*(det[j] - uv[k, j]), *uv[k, j], side, ang[k], j, mid, 2 * i + c,
                                 noise.get(mid, np.nan))
                            )  # fmt: skip
    out = {}
    for m, r in rows.items():
        a = np.asarray(r, dtype=float).reshape(-1, 10)
        out[m] = CornerOffsets(
            d=a[:, 0:2],
            uv=a[:, 2:4],
            size_px=a[:, 4],
            angle_deg=a[:, 5],
            corner=a[:, 6].astype(int),
            marker=a[:, 7].astype(int),
            image=a[:, 8].astype(int),
            sigma=a[:, 9],
            pose_err_m=pose_err,
            joint_quant_rad=quant,
            joint_err=np.asarray(jerr),
            joint_step=1.0 / np.asarray(setup.robot.counts_per_unit, dtype=float),
            joint_sigma=_read_back_sigma(setup.robot),
            intrinsics_err_px=intr_err,
        )
    return out


def _stats(d: np.ndarray) -> tuple[int, float, float, float]:
    """(corners, mean x, mean y, RMS of the 2D offset) of offsets ``d`` (n, 2) px."""
    if len(d) == 0:
        return 0, np.nan, np.nan, np.nan
    return (
        len(d),
        float(d[:, 0].mean()),
        float(d[:, 1].mean()),
        float(np.sqrt((d**2).sum(1).mean())),
    )


def outlier_detections(o: CornerOffsets, limit_px: float = 0.3) -> np.ndarray:
    """(n,) bool: corners of the detections (marker, image) with any corner more than
    ``limit_px`` from its analytic projection."""
    bad = np.linalg.norm(o.d, axis=1) > limit_px
    keys = {(m, i) for m, i in zip(o.marker[bad], o.image[bad], strict=True)}
    return np.array([(m, i) in keys for m, i in zip(o.marker, o.image, strict=True)], dtype=bool)


def summarise(
    o: CornerOffsets, width: int, height: int
) -> list[tuple[str, int, float, float, float]]:
    """Rows ``(group, corners, mean x, mean y, RMS)`` (px): all, the detections without any
    corner beyond 0.3 px, per marker size, per viewing angle, per corner index and per image
    region (3 x 3 grid of a ``width`` x ``height`` image)."""
    out = outlier_detections(o)
    rows = [("all", *_stats(o.d)), ("detections with every corner <= 0.3 px", *_stats(o.d[~out]))]
    rows.append(("detections with a corner > 0.3 px", *_stats(o.d[out])))
    for lo, hi in zip(SIZE_BINS_PX[:-1], SIZE_BINS_PX[1:], strict=True):
        sel = (o.size_px >= lo) & (o.size_px < hi)
        rows.append((f"size {lo:.0f}-{hi:.0f} px", *_stats(o.d[sel])))
    for lo, hi in zip(ANGLE_BINS_DEG[:-1], ANGLE_BINS_DEG[1:], strict=True):
        sel = (o.angle_deg >= lo) & (o.angle_deg < hi)
        rows.append((f"angle {lo:.0f}-{hi:.0f} deg", *_stats(o.d[sel])))
    for j in range(4):
        rows.append((f"corner {j}", *_stats(o.d[o.corner == j])))
    gx = np.clip((o.uv[:, 0] * 3 // width).astype(int), 0, 2)
    gy = np.clip((o.uv[:, 1] * 3 // height).astype(int), 0, 2)
    names = ("top", "middle", "bottom"), ("left", "centre", "right")
    for r in range(3):
        for c in range(3):
            rows.append(
                (f"region {names[0][r]}-{names[1][c]}", *_stats(o.d[(gy == r) & (gx == c)]))
            )
    return [r for r in rows if r[1] > 0]


def format_table(method: str, rows: list) -> str:
    """A Markdown table of :func:`summarise` rows for refinement ``method``."""
    lines = [
        f"| {method}: group | corners | mean x (px) | mean y (px) | RMS (px) |",
        "|---|---:|---:|---:|---:|",
    ]
    lines += [f"| {g} | {n} | {mx:+.3f} | {my:+.3f} | {r:.3f} |" for g, n, mx, my, r in rows]
    return "\n".join(lines)


def plot(results: dict[str, CornerOffsets], path: Path) -> None:
    """Offset magnitude against marker size and viewing angle, one colour per method (PNG at
    ``path``; its folder made if missing: ``--out DIR`` names a new folder)."""
    from selfcal.plots.plotting import legend_outside, pyplot, save_figure

    Path(path).parent.mkdir(parents=True, exist_ok=True)

    plt = pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for m, o in results.items():
        e = np.linalg.norm(o.d, axis=1)
        ax[0].scatter(o.size_px, e, s=4, alpha=0.5, label=m)
        ax[1].scatter(o.angle_deg, e, s=4, alpha=0.5, label=m)
    ax[0].set(xlabel="marker side (px)", ylabel="|detected - analytic| (px)", yscale="log")
    ax[1].set(xlabel="viewing angle (deg)", ylabel="|detected - analytic| (px)", yscale="log")
    legend_outside(ax[1])
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _read_back_sigma(robot) -> np.ndarray:
    """(n,) the read-back noise (rad / m) of ``robot``'s encoder table, inf without one."""
    from selfcal.estimation.joint_report import encoder_sigma

    sigma = encoder_sigma(robot)
    return np.full(robot.n, np.inf) if sigma is None else sigma


def _readback_line(o: CornerOffsets) -> str:
    """Per joint: the read-back rounding error's RMS in units of the encoder table's read-back
    sigma (the calibration's read-back prior) and its largest value in half steps."""
    rms = np.sqrt(np.mean(o.joint_err**2, axis=0)) / o.joint_sigma
    half = np.abs(o.joint_err).max(axis=0) / (o.joint_step / 2.0)
    return (
        "read-back - true joints per joint: RMS / read-back sigma "
        f"{' '.join(f'{v:.2f}' for v in rms)}; max / (step / 2) "
        f"{' '.join(f'{v:.2f}' for v in half)}; mean / step "
        f"{' '.join(f'{v:+.2f}' for v in o.joint_err.mean(axis=0) / o.joint_step)}"
    )


def main(
    config: str | Path | None = None,
    refine: tuple[str, ...] = ("lines", "lines-unscreened", "subpix"),
    figure: Path | None = None,
    max_poses: int | None = None,
    msaa: int | None = None,
    image_sigma: float = 0.0,
) -> str:
    """Measure (:func:`measure`), write the figure (if ``figure``) and return the Markdown
    report."""
    from selfcal.config.scenario import load_scenario

    s = load_scenario(config)
    res = measure(config, refine, max_poses, msaa, image_sigma)
    W, H = s.camera.true_model().width, s.camera.true_model().height
    first = next(iter(res.values()))
    parts = [
        f"camera pose MuJoCo vs actual chain: {first.pose_err_m * 1e3:.2e} mm; "
        f"reported (quantised) vs true joints: {np.degrees(first.joint_quant_rad):.4f} deg max; "
        f"MuJoCo's intrinsics vs the true camera: {first.intrinsics_err_px:.1e} px max",
        _readback_line(first),
    ]
    for m, o in res.items():
        line = f"{m}: marker scale error {o.scale_error():+.1e} (relative)"
        got, want = o.noise_check()
        if np.isfinite(want):
            line += (
                f"; corner error {got:.4f} px per coordinate, the detector's noise estimate "
                f"{want:.4f} px"
            )
        parts.append(line)
    parts += [format_table(m, summarise(o, W, H)) for m, o in res.items()]
    if figure is not None:
        plot(res, Path(figure))
    return "\n\n".join(parts)


DEFAULT_OUT = Path("runs") / "diagnose-render"
"""The output folder when ``--out`` is not given (relative to the working directory, like the
other commands' ``runs/...`` defaults)."""
FIGURE_NAME = "render_corners.png"


def figure_path(out: str | Path | None, figure: str | Path | None) -> Path:
    """Where the figure goes: ``figure`` when given, else ``OUT/figures/render_corners.png``
    (``OUT`` = ``out`` or :data:`DEFAULT_OUT`), like the figures of ``selfcal run``."""
    if figure is not None:
        return Path(figure)
    return Path(out if out is not None else DEFAULT_OUT) / "figures" / FIGURE_NAME


def _add_args(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("config", nargs="?", default=None, help="scenario TOML (default: paper.toml)")
    ap.add_argument(
        "--out",
        default=None,
        metavar="DIR",
        help=f"output folder (default {DEFAULT_OUT}); the figure goes to DIR/figures/{FIGURE_NAME}",
    )
    ap.add_argument(
        "--figure",
        type=Path,
        default=None,
        metavar="PNG",
        help=f"write the figure here instead of DIR/figures/{FIGURE_NAME} (e.g. "
        f"docs/{FIGURE_NAME} to update the docs' figure)",
    )
    ap.add_argument("--refine", nargs="+", default=["lines", "lines-unscreened", "subpix"])
    ap.add_argument("--msaa", type=int, default=None, help="multisample count (default: 4)")
    ap.add_argument(
        "--image-sigma",
        type=float,
        default=0.0,
        metavar="GREY",
        help="the simulator's image noise, grey levels (default 0: noise-free)",
    )


def _cmd(a: argparse.Namespace) -> int:
    figure = figure_path(a.out, a.figure)
    print(main(a.config, tuple(a.refine), figure, msaa=a.msaa, image_sigma=a.image_sigma))
    from selfcal.console.common import note_written

    note_written(a, figure)
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal diagnose render [scenario.toml] [--out DIR] [--figure PNG] [--refine M
    ...]``."""
    sp = subparsers.add_parser("diagnose", help="diagnostics of the simulated pipeline")
    sub = sp.add_subparsers(dest="what", required=True)
    r = sub.add_parser(
        "render",
        help="rendered corners against their analytic projection (docs/accuracy.md)",
        description=__doc__.splitlines()[0],
    )
    _add_args(r)
    r.set_defaults(func=_cmd)
    return sp


if __name__ == "__main__":
    ap = module_parser(__file__, description=__doc__.splitlines()[0])
    _add_args(ap)
    raise SystemExit(_cmd(ap.parse_args()))
