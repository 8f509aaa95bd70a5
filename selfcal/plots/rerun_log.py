"""Record a finished run into a Rerun ``.rrd`` file (post hoc, from the dataset folder).

``record_run(dataset_dir, rrd_path)`` reads ``dataset.json``, ``joints.csv``, the images or
detections, ``calibration.json`` and (simulation) ``truth.json``; acquisition is untouched. Logged
(world frame = the simulator's world, metres; timeline ``frame`` = dataset frame index):

- ``world/robot``: the robot's visual geometry (boxes, cylinders, capsules, spheres from the MJCF
  built by ``selfcal.sim.robot_mjcf`` for the true chain of ``truth.json``, else the nominal one) at every
  frame, posed from MuJoCo's ``geom_xpos``/``geom_xmat``; ``world/scene``: table and markers.
- ``world/estimate/cam_<name>``: one entity per camera of the dataset's rig (``cam_left`` for
  one camera, ``cam_left`` and ``cam_right`` for the stereo pair): the self-calibrated camera
  poses (frusta with the estimated intrinsics) with their images (images datasets) and detected
  corners; ``world/truth/cam_<name>``: the true camera frusta (simulation).
- ``world/estimate/points``: marker corners triangulated from the estimated cameras, and
  ``world/estimate/scale_bar`` between the two scale markers' centres (``world/truth/...`` alike).
- ``errors/...`` scalars on the ``frame`` timeline: camera position / rotation error against the
  truth, identification residual of the calibrated model per pose, reprojection RMS per pose; and
  on the ``identification_iteration`` timeline the pose residual RMS before (0) and after (the
  iteration count) identification. ``calibration.json`` holds no per-iteration history, which
  ``notes`` says.

The estimate lives in its reconstruction frame; it is registered to the world by the best rigid
alignment (no scale) of the recovered left-camera centres onto the true ones (onto the nominal
model's camera centres when there is no ``truth.json``, e.g. on hardware). A board run (the
known-board route's ``calibration.json``) is recorded by :mod:`selfcal.plots.rerun_board` (the
board's points, the cameras posed by the calibrated chain).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from selfcal.console.common import note_written
from selfcal.console.progress import Progress
from selfcal.plots.rerun_board import record_board_run
from selfcal.plots.rerun_parts import EST_COLOR, GT_COLOR, archetypes, log_camera, open_recording

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = ["record_run", "register"]


def record_run(
    dataset_dir: str | Path, rrd_path: str | Path | None, spawn: bool = False
) -> Path | None:
    """Record the finished run in ``dataset_dir`` into ``rrd_path`` (and/or a spawned viewer).

    Needs ``dataset.json``, ``joints.csv`` and ``calibration.json``; ``truth.json`` is used when
    present. Returns the ``.rrd`` path (``None`` only when ``spawn`` without a path).

    Raises:
        DatasetError: missing dataset or calibration files (the message names the fix).
    """
    import rerun as rr  # optional, ~0.6 s to import: only when recording

    from selfcal.calibration.field.calibrate import detect_dataset
    from selfcal.camera import CameraSet, Rig
    from selfcal.camera.camera_set import unproject_views
    from selfcal.estimation.observations import Observations
    from selfcal.estimation.reprojection import reprojection_residuals
    from selfcal.estimation.triangulation import triangulate
    from selfcal.io.board_calibration import calibration_kind
    from selfcal.io.calibration import read_calibration
    from selfcal.io.dataset import Dataset, DatasetError
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.accuracy import kabsch
    from selfcal.kinematics.forward import fk_tool
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import load_robot
    from selfcal.sim.actual import marker_field_of
    from selfcal.sim.markers import make_marker_field
    from selfcal.sim.posed_geometry import PosedGeometry
    from selfcal.sim.robot_mjcf import RigConfig
    from selfcal.target import CORNERS_PER_MARKER, marker_corner, marker_features
    from selfcal.transforms import inv_pose

    root = Path(dataset_dir)
    ds = Dataset.open(root)
    cal_path = root / "calibration.json"
    if not cal_path.is_file():
        raise DatasetError(f"{cal_path} is missing: run `selfcal calibrate {root}` first")
    if calibration_kind(cal_path) == "board":  # the known-board route's calibration
        rrd_board = None if rrd_path is None else Path(rrd_path)
        return record_board_run(root, rrd_board, spawn)
    cal = read_calibration(cal_path)
    robot = load_robot(ds.info.robot_model)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    truth = read_truth(root / "truth.json") if (root / "truth.json").is_file() else None

    cams = tuple(ds.info.cameras)  # ("left",) or ("left", "right")
    # the estimated models, lenses included: each camera's own, or the one shared
    est_cams = tuple(cal.intrinsics_of(c).camera() for c in range(len(cams)))
    est_intr = est_cams[0]
    est_set = CameraSet(est_cams, cams) if len(cams) > 1 and cal.cameras else est_intr
    T_first_cam = np.stack([np.eye(4), cal.rig.T_left_right_m][: len(cams)])
    if not np.isfinite(T_first_cam).all():
        raise DatasetError(
            f"{cal_path}: the dataset has cameras {list(cams)} but the calibration has no "
            "right camera (a one-camera calibration)",
            fix=f"run `selfcal calibrate {root}` again",
        )
    rig_est = Rig(est_cams, T_first_cam, cams)
    cp = cal.camera_poses
    est_pose = dict(zip(cp.frame_index, cp.T_world_cam_left_m))
    q_read = {int(i): np.radians(q) for i, q in zip(ds.indices, ds.joints_deg)}
    true_frame = {
        f.frame_index: f for f in (truth.frames if truth else ()) if f.frame_index is not None
    }

    # Register the reconstruction frame to the world (see module docstring).
    common = sorted(set(est_pose) & (set(true_frame) if truth else set(q_read)))
    A = np.array([est_pose[i][:3, 3] for i in common])
    if truth is not None:
        B = np.array([true_frame[i].T_world_cam_left[:3, 3] for i in common])
    else:
        B = fk_tool(nominal, np.array([q_read[i] for i in common]))[:, :3, 3]
    T_world_recon = kabsch(A, B) if len(common) >= 3 else np.eye(4)
    est_world = {i: T_world_recon @ T for i, T in est_pose.items()}

    # Detections (images: detect again; analytic: stored).
    dets = detect_dataset(ds).detections

    # Triangulated points from the estimated cameras (reconstruction frame -> world).
    frames = sorted(est_pose)
    row = {i: k for k, i in enumerate(frames)}
    obs = Observations.from_corners(
        {(row[int(i)], cam): m for (i, cam), m in dets.items() if int(i) in row},
        len(frames),
        cameras=cams,
    )
    T_first_world = inv_pose(np.stack([est_pose[i] for i in frames]).reshape(-1, 4, 4))
    T_cw = obs.layout.by_view(rig_est.T_cams_world(T_first_world))
    ids, pidx = obs.point_index()
    X_all, n_seen = triangulate(
        T_cw, obs.view, pidx, unproject_views(est_set, obs.uv, obs.view), len(ids)
    )
    ok = n_seen >= 2
    keys, X_recon = ids[ok], X_all[ok]
    X_world = X_recon @ T_world_recon[:3, :3].T + T_world_recon[:3, 3]
    r, _ = reprojection_residuals(est_set, T_cw, X_all, obs.view, pidx, obs.uv)
    err2 = np.sum(r**2, axis=1)

    # Per-pose reprojection RMS with the triangulated points.
    def reproj_rms(i: int) -> float:
        rows = (obs.config == row.get(i, -1)) & ok[pidx]
        return float(np.sqrt(np.mean(err2[rows]))) if rows.any() else float("nan")

    # Identification residual per pose (truth-free): calibrated model FK vs the camera pose.
    est_model = cal.model
    fr_used = sorted(est_pose)
    T_fk = fk_tool(est_model, np.array([q_read[i] for i in fr_used]))
    ident_res = {}
    for i, T in zip(fr_used, T_fk):
        D = inv_pose(est_pose[i]) @ T
        ang = np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
        ident_res[i] = (float(np.linalg.norm(D[:3, 3]) * 1000), float(ang))

    # Geometry: true chain when known, else nominal.
    if truth is not None:
        chain = truth.true_model
        rig = RigConfig(intrinsics=truth.intrinsics_left, T_left_right=truth.T_left_right,
                        intrinsics_right=truth.intrinsics_right)  # fmt: skip
        field = marker_field_of(truth)
    else:
        chain, rig, field = nominal, RigConfig(), make_marker_field()
    geo = PosedGeometry(robot, chain, rig, field)

    rrd = Path(rrd_path) if rrd_path is not None else None
    rec = open_recording(root, rrd, spawn, "record_run")

    # Static: scene, points, scale bar, trajectories, notes.
    geo.set(robot.home)
    for key, arch in archetypes(geo, geo.static if truth is not None else []).items():
        rec.log(f"world/scene/{key}", arch, static=True)
    if truth is not None:
        rec.log(
            "world/truth/marker_corners",
            rr.Points3D(field.corners_world().reshape(-1, 3), radii=0.0015, colors=GT_COLOR),
            static=True,
        )
    if len(X_world):
        rec.log(
            "world/estimate/points",
            rr.Points3D(
                X_world,
                radii=0.002,
                colors=EST_COLOR,
                labels=[f"{m}:{k}" for m, k in zip(*marker_corner(keys))],
                show_labels=False,
            ),
            static=True,
        )
    sid = tuple(ds.info.scale_ids)
    cen = {}
    for mid in sid:
        c = X_world[np.isin(keys, marker_features(mid))]
        if len(c) == CORNERS_PER_MARKER:
            cen[mid] = c.mean(axis=0)
    if len(cen) == 2:
        length = np.linalg.norm(cen[sid[0]] - cen[sid[1]]) * 1000
        rec.log(
            "world/estimate/scale_bar",
            rr.LineStrips3D(
                [[cen[sid[0]], cen[sid[1]]]],
                radii=0.002,
                colors=EST_COLOR,
                labels=[f"d = {length:.2f} mm (known {ds.info.scale_length_m * 1000:.1f})"],
            ),
            static=True,
        )
    if truth is not None:
        c_true = field.centers_world()
        a, b = field.index_of(sid[0]), field.index_of(sid[1])
        rec.log(
            "world/truth/scale_bar",
            rr.LineStrips3D([[c_true[a], c_true[b]]], radii=0.001, colors=GT_COLOR),
            static=True,
        )
    if est_world:
        rec.log(
            "world/estimate/camera_path",
            rr.LineStrips3D(
                [[est_world[i][:3, 3] for i in sorted(est_world)]], radii=0.0008, colors=EST_COLOR
            ),
            static=True,
        )
    if truth is not None and true_frame:
        rec.log(
            "world/truth/camera_path",
            rr.LineStrips3D(
                [[true_frame[i].T_world_cam_left[:3, 3] for i in sorted(true_frame)]],
                radii=0.0008,
                colors=GT_COLOR,
            ),
            static=True,
        )
    ident = cal.identification
    pr = {"before": ident.pose_residual_rms.before, "after": ident.pose_residual_rms.after}
    note = (
        "# scorbot-selfcal run\n\n"
        f"dataset `{root}`; {len(ds.indices)} frames, {len(est_pose)} registered; observation "
        f"{ds.info.observation}; truth: {'yes' if truth else 'no (hardware?)'}.\n\n"
        f"fx = {est_intr.fx:.2f} px, mu = {est_intr.mu:.5f}, reprojection RMS "
        f"{cal.reprojection_rms_px:.3f} px.\n\n"
        "Per-iteration residuals: calibration.json does not record them (only the pose residual "
        "RMS before and after identification and the iteration count), so the "
        "`identification_iteration` timeline holds just those two points.\n\n"
        "The estimate is registered to the world by the best rigid alignment of the recovered "
        "camera centres onto the "
        f"{'true' if truth else 'nominal-model'} ones."
    )
    rec.log("notes", rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)
    for it, which in ((0, "before"), (max(ident.iterations, 1), "after")):
        rec.set_time("identification_iteration", sequence=it)
        rec.log("errors/identification/pose_residual_rms_mm", rr.Scalars(pr[which].mm))
        rec.log("errors/identification/pose_residual_rms_deg", rr.Scalars(pr[which].deg))
    rec.reset_time()

    # Per frame.
    for i, q in sorted(q_read.items()):
        rec.set_time("frame", sequence=i)
        fr = true_frame.get(i)
        geo.set(fr.joints_rad if fr is not None else q)
        for key, arch in archetypes(geo, geo.moving).items():
            rec.log(f"world/robot/{key}", arch)
        rec.log("joints_deg", rr.Scalars(np.degrees(q)))
        if fr is not None and truth is not None:
            for cam in cams:
                left = cam == "left"
                log_camera(
                    rec,
                    f"world/truth/cam_{cam}",
                    fr.T_world_cam_left if left else fr.T_world_cam_right,
                    truth.intrinsics_left if left else truth.intrinsics_right,
                    GT_COLOR,
                )
        if i in est_world:
            for c, cam in enumerate(cams):
                T = est_world[i] @ T_first_cam[c]
                img = ds.frame_paths(i)[c] if ds.info.observation == "images" else None
                log_camera(
                    rec,
                    f"world/estimate/cam_{cam}",
                    T,
                    est_cams[c],
                    EST_COLOR,
                    img,
                    dets.get((i, cam), {}),
                )
            rec.log("errors/reprojection_rms_px", rr.Scalars(reproj_rms(i)))
            rec.log("errors/identification/residual_mm", rr.Scalars(ident_res[i][0]))
            rec.log("errors/identification/residual_deg", rr.Scalars(ident_res[i][1]))
            if fr is not None:
                Tt = fr.T_world_cam_left
                D = inv_pose(Tt) @ est_world[i]
                ang = np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
                rec.log(
                    "errors/camera_vs_truth/position_mm",
                    rr.Scalars(float(np.linalg.norm(D[:3, 3]) * 1000)),
                )
                rec.log("errors/camera_vs_truth/rotation_deg", rr.Scalars(float(ang)))
    rec.flush()
    rec.disconnect()
    return rrd


def _cmd(args: argparse.Namespace) -> int:
    rrd = args.rrd or (None if args.spawn else Path(args.dataset) / "run.rrd")
    quiet = getattr(args, "quiet", False)  # a parser built by a caller may lack -q
    with Progress("record", enabled=not quiet).step(f"recording {args.dataset}") as st:
        path = record_run(Path(args.dataset), rrd, spawn=args.spawn)
        st.result("viewer spawned" if path is None else f"{path}")
    if path is not None:
        note_written(args, path)
        print(f"recorded {args.dataset} into {path} (view: rerun {path})")
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal record DIR --rrd FILE [--spawn]`` to an argparse subparsers object."""
    sp = subparsers.add_parser(
        "record",
        help="record a finished run into a Rerun .rrd file (robot, cameras, points, errors)",
        description="Record a finished run (dataset folder with calibration.json; truth.json "
        "used when present) into a Rerun .rrd file; --spawn also opens the viewer.",
    )
    sp.add_argument("dataset", help="dataset folder of a finished run")
    sp.add_argument(
        "--rrd",
        default=None,
        help="output .rrd file (default DATASET/run.rrd; with --spawn and no --rrd: the viewer only)",
    )
    sp.add_argument("--spawn", action="store_true", help="spawn the Rerun viewer")
    sp.set_defaults(func=_cmd)
    return sp
