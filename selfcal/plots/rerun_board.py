"""Record a finished *board* run (``calibration.json`` of the board route) into a Rerun ``.rrd``.

:func:`selfcal.plots.rerun_log.record_run` hands a board calibration here. Logged (world frame = the
simulator's world with ``truth.json``, else the board frame; metres; timeline ``frame`` = dataset
frame index):

- ``world/board/points``: the board's feature points (the board frame is the estimate's world:
  placed by ``truth.json``'s board pose in simulation) and ``world/board/outline``;
- ``world/robot``: the robot's visual geometry (the true chain in simulation, else the nominal
  one) at every frame;
- ``world/estimate/cam_<name>``: one entity per camera of the dataset's rig, posed by the
  calibrated chain at the joint read-back (and the calibrated extrinsics), its frustum with the
  calibrated camera, its image (images datasets) and the board features found in it;
  ``world/truth/cam_<name>``: the true cameras (simulation);
- ``errors/...`` scalars on the ``frame`` timeline: the first camera's position / rotation error
  against the truth and the reprojection RMS of the board's points.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from selfcal.plots.rerun_parts import EST_COLOR, GT_COLOR, archetypes, log_camera, open_recording

__all__ = ["record_board_run"]


def _angle_deg(D: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1))))


def record_board_run(root: Path, rrd: Path | None, spawn: bool = False) -> Path | None:
    """Record the finished board run in ``root`` into ``rrd`` (and/or a spawned viewer); see
    the module docstring. Returns ``rrd``.

    Raises:
        DatasetError, BoardCalibrationFileError: missing or damaged dataset or calibration.
    """
    import rerun as rr  # optional, ~0.6 s to import: only when recording

    from selfcal.calibration.board.dataset import dataset_board, detect_board
    from selfcal.io.board_calibration import read_board_calibration
    from selfcal.io.dataset import Dataset
    from selfcal.io.truth import read_truth
    from selfcal.kinematics.forward import fk_tool
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.robot.definition import load_robot
    from selfcal.sim.posed_geometry import PosedGeometry
    from selfcal.sim.robot_mjcf import RigConfig
    from selfcal.transforms import inv_pose

    ds = Dataset.open(root)
    cal = read_board_calibration(root / "calibration.json")
    board = dataset_board(ds)
    robot = load_robot(ds.info.robot_model)
    truth = read_truth(root / "truth.json") if (root / "truth.json").is_file() else None
    T_world_board = np.eye(4)
    if truth is not None and truth.T_world_board is not None:
        T_world_board = truth.T_world_board
    cams = tuple(ds.info.cameras)
    T_first_cam = np.eye(4)[None] if cal.T_first_cam is None else cal.T_first_cam
    q_read = np.radians(ds.joints_deg)
    T_est = T_world_board @ fk_tool(cal.model, q_read)  # first camera -> world, per frame
    found = {c: detect_board(ds, board, c)[0] for c in cams}
    true_frame = {f.frame_index: f for f in (truth.frames if truth else ())}

    rec = open_recording(root, rrd, spawn, "record_board_run")

    ids, pts = board.layout()
    X = pts @ T_world_board[:3, :3].T + T_world_board[:3, 3]
    rec.log("world/board/points",
            rr.Points3D(X, radii=0.0015, colors=GT_COLOR, labels=[str(i) for i in ids],
                        show_labels=False), static=True)  # fmt: skip
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    rect = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0],
                     [lo[0], lo[1], 0]])  # fmt: skip
    rect = rect @ T_world_board[:3, :3].T + T_world_board[:3, 3]
    rec.log("world/board/outline", rr.LineStrips3D([rect], radii=0.001), static=True)
    rec.log("world/estimate/camera_path",
            rr.LineStrips3D([T_est[:, :3, 3]], radii=0.0008, colors=EST_COLOR), static=True)  # fmt: skip
    if truth is not None:
        chain = truth.true_model
        rig = RigConfig(intrinsics=truth.intrinsics_left, T_left_right=truth.T_left_right)
    else:
        chain = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
        rig = RigConfig()
    geo = PosedGeometry(robot, chain, rig, None)  # a board's scene: no marker field
    note = (
        f"# scorbot-selfcal board run\n\ndataset `{root}`; {len(ds.indices)} frames, "
        f"{cal.frames_used} used; target {cal.target.get('type')}; observation "
        f"{ds.info.observation}; truth: {'yes' if truth else 'no (hardware?)'}; reprojection "
        f"RMS {cal.reprojection_rms_px:.3f} px. The board frame is the calibration's world"
        f"{', placed by truth.json' if truth else ''}."
    )
    rec.log("notes", rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)

    for k, i in enumerate(ds.indices.tolist()):
        rec.set_time("frame", sequence=int(i))
        fr = true_frame.get(int(i))
        geo.set(fr.joints_rad if fr is not None else q_read[k])
        for key, arch in archetypes(geo, geo.moving).items():
            rec.log(f"world/robot/{key}", arch)
        rec.log("joints_deg", rr.Scalars(ds.joints_deg[k]))
        for c, cam in enumerate(cams):
            f = found[cam][k]
            img = ds.frame_paths(int(i))[c] if ds.info.observation == "images" else None
            log_camera(rec, f"world/estimate/cam_{cam}", T_est[k] @ T_first_cam[c],
                       cal.cameras[c], EST_COLOR, img,
                       {int(j): uv[None] for j, uv in zip(f.ids, f.uv)})  # fmt: skip
            if fr is not None and truth is not None:
                T_true = fr.T_world_cam_left if c == 0 else fr.T_world_cam_right
                true_cam = truth.intrinsics_left if c == 0 else truth.intrinsics_right
                log_camera(rec, f"world/truth/cam_{cam}", T_true, true_cam, GT_COLOR)
        f = found[cams[0]][k]
        if len(f):
            T_cb = inv_pose(T_est[k]) @ T_world_board
            uv = cal.cameras[0].project(board.points(f.ids) @ T_cb[:3, :3].T + T_cb[:3, 3])
            rms = float(np.sqrt(np.mean(np.sum((uv - f.uv) ** 2, axis=1))))
            rec.log("errors/reprojection_rms_px", rr.Scalars(rms))
        if fr is not None:
            D = inv_pose(fr.T_world_cam_left) @ T_est[k]
            rec.log("errors/camera_vs_truth/position_mm",
                    rr.Scalars(float(np.linalg.norm(D[:3, 3]) * 1000)))  # fmt: skip
            rec.log("errors/camera_vs_truth/rotation_deg", rr.Scalars(_angle_deg(D)))
    rec.flush()
    rec.disconnect()
    return rrd
