"""Backends behind the one Robot interface, chosen by ``[robot] backend`` in the scenario.

``sim``: the simulated actual robot (nominal + injected errors) photographing a marker field;
``hardware``: the ACL serial adapter (``hw``). Everything backend-specific lives here; the
acquisition loop and the calibration only see a ``Robot`` and a dataset. The simulator's set-up of
a scenario (the actual robot, the true cameras, the target) is
:mod:`selfcal.acquisition.simulator_setup`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from selfcal.acquisition.acquire import AcquisitionHooks
from selfcal.acquisition.simulator_setup import (
    DICTIONARY,
    SCALE_IDS,
    SimSetup,
    check_board_above_table,
    field_center,
    scenario_board_pose,
    sim_setup,
)
from selfcal.camera import Intrinsics, Rig
from selfcal.config.scenario import (
    CameraConfig,
    ConfigError,
    NoiseConfig,
    Scenario,
    joints_path,
    load_scenario,
    scenario_board,
    scenario_to_dict,
)
from selfcal.errors import InternalError
from selfcal.io.atomic import write_image_atomic
from selfcal.io.dataset_info import DatasetInfo, scenario_digest
from selfcal.io.target_toml import target_document
from selfcal.io.truth import (
    TRUTH_JOURNAL,
    append_truth_frame,
    read_truth,
    with_journal,
    write_truth,
)
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import (
    nominal_mcpc,
)
from selfcal.kinematics.self_collision import CapsuleChain
from selfcal.kinematics.trajectory import (
    check_not_degenerate,
    plan_postures,
)
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.robot.interface import Robot
from selfcal.sim.analytic import project_board, project_markers
from selfcal.sim.collision import collision_checker
from selfcal.sim.kinematic_robot import KinematicRobot
from selfcal.sim.sim_robot import SimRobot
from selfcal.target import CORNERS_PER_MARKER
from selfcal.transforms import trans

__all__ = [
    "make_sim_robot",
    "make_kinematic_robot",
    "open_robot",
    "plan_dataset",
    "render_posture",
]


def _file_postures(s: Scenario, robot: RobotDef) -> np.ndarray:
    """The postures (m, n) rad of ``[trajectory] joints`` (kind "file")."""
    path = joints_path(s)
    if not path.is_file():
        raise ConfigError(f"{s.source}: trajectory.joints = {s.trajectory.joints!r}: no such file "
                          f"{path}", fix="give a joints CSV relative to the scenario file")  # fmt: skip
    # Here, not at the top: the joints' reader comes with the tracker's estimation and so the
    # solver and scipy, which a run with planned postures needs only once it calibrates (#32).
    from selfcal.io.tracker import read_joints

    return read_joints(path, robot, "deg", guess=False)


def planning_inputs(s: Scenario) -> dict:
    """What trajectories are planned with: robot, nominal camera chain, the camera rig (nominal
    intrinsics and baseline), a 6 x 6 grid of points (with normals) over the target region and
    the self-collision check (:class:`selfcal.kinematics.self_collision.CapsuleChain` of the nominal arm).

    Planning sees only what a person at a real robot knows: the region the target covers (centred
    where the home posture looks, ``[target] extent_mm``; a board's own extent, its corner
    features' span), never the true marker positions, so the sim and hardware backends plan the
    same postures for one scenario.
    """
    robot = load_robot(s.robot.model)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    board = scenario_board(s)
    if board is None or not s.target.board_pose:  # the target where the home posture looks
        cx, cy = field_center(robot, nominal)  # (refused when it does not look at the table)
        if board is None:
            half_x = half_y = s.target.extent_mm / 2000.0
        else:  # the span of the board's features
            _, pts_b = board.layout()
            half_x, half_y = (pts_b[:, :2].max(axis=0) - pts_b[:, :2].min(axis=0)) / 2
        pts = np.array(
            [[cx + a, cy + b, 0.0] for a in np.linspace(-half_x, half_x, 6)
             for b in np.linspace(-half_y, half_y, 6)]
        )  # fmt: skip
        normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    else:  # the grid over the board where [target] board_pose puts it
        _, pts_b = board.layout()
        lo, hi = pts_b[:, :2].min(axis=0), pts_b[:, :2].max(axis=0)
        grid = np.array([[a, b, 0.0] for a in np.linspace(lo[0], hi[0], 6)
                         for b in np.linspace(lo[1], hi[1], 6)])  # fmt: skip
        T = scenario_board_pose(s, board, robot, nominal)
        pts = grid @ T[:3, :3].T + T[:3, 3]
        normals = np.tile(-T[:3, 2], (len(pts), 1))
    return {
        "robot": robot,
        "model_cam": nominal,
        "rig": _planning_rig(s),
        "points_world": pts,
        "normals_world": normals,
        "min_visible": s.trajectory.min_markers,
        "collision_ok": CapsuleChain(nominal_mcpc(robot), robot.T_flange_cam).ok,
    }


def _planning_rig(s: Scenario) -> Rig:
    """The cameras the plan must serve: the nominal stereo pair, or its left camera alone."""
    W, H = s.camera.resolution
    left, right = (s.camera.of(n) for n in ("left", "right"))
    rig = Rig.stereo(
        Intrinsics.centered(left.fx, left.mu, W, H),
        trans(np.array([s.camera.baseline_mm / 1000, 0.0, 0.0])),
        Intrinsics.centered(right.fx, right.mu, W, H),
    )
    n = s.camera.count
    return Rig(rig.cameras[:n], rig.T_first_cam[:n], rig.names[:n])


def plan_optimal(s: Scenario, *, collisions: bool = True, **kw):
    """The D-optimal plan (:class:`selfcal.calibration.field.optimal_poses.OptimalPlan`, ``q`` rad) for scenario ``s``
    over the planning grid of :func:`planning_inputs`, checked for self-collision with MuJoCo
    (:mod:`selfcal.sim.collision`), with ``corners_per_point = corners of the markers / 36``."""
    # Here, not at the top: the planner loads scipy.linalg, which a run with planned random postures
    # (the default scenario) needs only once it calibrates (issue #32).
    from selfcal.calibration.field.optimal_poses import plan_optimal_postures

    inp = planning_inputs(s)
    inp.pop("collision_ok")  # the MuJoCo shapes below check it
    corners = CORNERS_PER_MARKER * s.target.markers
    kw.setdefault("corners_per_point", corners / len(inp["points_world"]))
    kw.setdefault("pixel_sigma_px", s.noise.pixel_sigma)
    return plan_optimal_postures(
        **inp,
        n_poses=s.trajectory.poses,
        seed=s.trajectory.seed,
        collision_ok=collision_checker(s.robot.model) if collisions else None,
        **kw,
    )


def plan_dataset(s: Scenario, setup: SimSetup | None = None) -> DatasetInfo:
    """The dataset description: planned trajectory and validation postures (deg).

    ``[trajectory] kind = "optimal"`` selects D-optimal postures (``selfcal.calibration.field.optimal_poses``)
    instead of random ones, under the same visibility rule and without self-collision.
    Eye-to-hand (``[camera] setup``) the postures show the board on the flange to the static
    camera (:func:`selfcal.acquisition.eye_to_hand.plan_static`).
    """
    if s.camera.setup == "eye-to-hand":
        return _static_info(s)
    p = planning_inputs(s)
    robot, nominal, rig = p["robot"], p["model_cam"], p["rig"]
    pts, nrm = p["points_world"], p["normals_world"]
    W, H = rig.cameras[0].width, rig.cameras[0].height
    fld = None if setup is None else setup.field
    scale_ids = SCALE_IDS if fld is None else (int(fld.scale_ids[0]), int(fld.scale_ids[1]))
    if s.trajectory.kind == "optimal":
        q = plan_optimal(s).q
    elif s.trajectory.kind == "file":
        q = _file_postures(s, robot)
    else:
        q = plan_postures(
            robot,
            nominal,
            rig,
            pts,
            s.trajectory.poses,
            seed=s.trajectory.seed,
            min_visible=s.trajectory.min_markers,
            normals_world=nrm,
            collision_ok=p["collision_ok"],
        )
    check_not_degenerate(fk_tool(nominal, q))
    qv = plan_postures(
        robot,
        nominal,
        rig,
        pts,
        s.validation.poses,
        seed=10_000 + s.validation.seed,
        min_visible=0,
        normals_world=nrm,
        collision_ok=p["collision_ok"],
    )
    return DatasetInfo(
        robot_model=robot_reference(s.robot.model),
        encoder_model=robot_reference(
            s.robot.model
        ),  # the read-back: quantised (sim) or counts (hardware) by it
        backend=s.robot.backend,
        resolution=(W, H),
        dictionary=DICTIONARY,
        scale_ids=scale_ids,
        scale_length_m=s.target.scale_length_mm / 1000,
        observation="images" if (s.noise.render or s.robot.backend == "hardware") else "detections",
        planned_joints_deg=np.round(np.degrees(q), 6),
        validation_joints_deg=np.round(np.degrees(qv), 6),
        provenance={"scenario_sha256": scenario_digest(_digested(s))},
        camera_model=s.camera.model,
        camera_free=tuple(s.camera.free),
        cameras=s.camera.names,
        camera_models=_camera_models(s),
        per_camera_intrinsics=s.camera.own_intrinsics,
        board=None if (board := scenario_board(s)) is None else target_document(board),
    )


def _static_info(s: Scenario) -> DatasetInfo:
    """:func:`plan_dataset` of an eye-to-hand scenario."""
    from selfcal.acquisition.eye_to_hand import plan_static  # lazy: see open_robot

    robot = load_robot(s.robot.model)
    q, qv = plan_static(s, robot, _file_postures(s, robot) if s.trajectory.kind == "file" else None)
    board = scenario_board(s)
    if board is None:  # pragma: no cover - validate_camera refuses eye-to-hand without one
        raise InternalError(f"{s.source}: an eye-to-hand scenario without a [target] board")
    W, H = s.camera.resolution
    return DatasetInfo(
        robot_model=robot_reference(s.robot.model), encoder_model=robot_reference(s.robot.model),
        backend=s.robot.backend, resolution=(int(W), int(H)), dictionary=DICTIONARY,
        scale_ids=SCALE_IDS, scale_length_m=s.target.scale_length_mm / 1000,
        observation="images" if s.noise.render else "detections",
        planned_joints_deg=np.round(np.degrees(q), 6),
        validation_joints_deg=np.round(np.degrees(qv), 6),
        provenance={"scenario_sha256": scenario_digest(_digested(s))},
        camera_model=s.camera.model, camera_free=tuple(s.camera.free), cameras=s.camera.names,
        board=target_document(board), setup="eye-to-hand",
    )  # fmt: skip


def _camera_models(s: Scenario) -> tuple[tuple[str, tuple[str, ...]], ...] | None:
    """(model, free) of each camera when they differ (``[camera.right]``), else None."""
    kinds = tuple((c.model, tuple(c.free)) for c in map(s.camera.of, s.camera.names))
    return kinds if len(set(kinds)) > 1 else None


def _digested(s: Scenario) -> dict:
    """The scenario as its dataset's digest sees it: ``noise.msaa`` at its default, an empty
    ``target.board`` (the marker field), an empty ``camera.right``, a zero ``camera.skew_px``,
    the camera on the flange (``camera.setup``) and no ``camera.pose`` are left out, so a dataset acquired before the keys existed (with those defaults) still
    resumes."""
    d = scenario_to_dict(s)
    if s.noise.msaa == NoiseConfig.msaa:
        del d["noise"]["msaa"]
    if not s.target.board:
        del d["target"]["board"]
    if not s.target.board_pose:
        del d["target"]["board_pose"]
    if not s.trajectory.joints:
        del d["trajectory"]["joints"]
    if not s.camera.right:
        del d["camera"]["right"]
    if s.camera.skew_px == CameraConfig.skew_px:
        del d["camera"]["skew_px"]
    if s.camera.setup == CameraConfig.setup:
        del d["camera"]["setup"]
    if not s.camera.pose:
        del d["camera"]["pose"]
    return d


def open_robot(
    s: Scenario, out: Path, setup: SimSetup | None = None
) -> tuple[Robot, AcquisitionHooks]:
    """The scenario's robot and its simulator-only hooks (analytic detections, ground truth)."""
    if s.robot.backend == "hardware":
        # the serial link's modules (pyserial, the ACL driver) load for a robot that uses them
        from selfcal.acquisition.hardware import open_hardware_robot

        return open_hardware_robot(s), AcquisitionHooks()

    setup = setup or sim_setup(s)
    # the analytic path needs no images: the MuJoCo-free simulator serves any serial arm
    if setup.static is not None:
        # the still camera's simulator (its scene and the board's placement: 0.05-0.1 s of
        # imports) loads for an eye-to-hand scenario only
        from selfcal.acquisition.eye_to_hand import static_detect, static_robot

        still = static_robot(s, setup.static)
        robot: KinematicRobot = still
    elif s.noise.render:
        robot = make_sim_robot(s, setup)
    else:
        robot = make_kinematic_robot(s, setup)
    rig = robot.rig
    truth = robot.truth(meta={"scenario": scenario_to_dict(s)})
    truth_path = Path(out) / "truth.json"
    journal = Path(out) / TRUTH_JOURNAL
    if truth_path.is_file():
        truth = dataclasses.replace(truth, frames=read_truth(truth_path).frames)
    truth = with_journal(truth, journal)  # frames of a killed acquisition
    write_truth(truth_path, truth)
    journal.unlink(missing_ok=True)
    rng = np.random.default_rng(s.noise.seed + 7919)
    fld = setup.field  # the markers' ids, corners and normals (world); a board scenario has none
    marks = None if fld is None else (fld.ids, fld.corners_world(), fld.T_world_marker[:, :3, 2])

    def record_truth(index: int) -> None:
        nonlocal truth
        truth = truth.with_frame(robot.truth_frame(), frame_index=index)
        append_truth_frame(journal, truth.frames[-1])  # O(1); truth.json once, in finish()

    def finish() -> None:
        write_truth(truth_path, truth)
        journal.unlink(missing_ok=True)

    def detect() -> dict[str, dict[int, np.ndarray]]:
        fr = robot.truth_frame()
        board = setup.board_pose()
        out_ = {}
        for cam, T, intr in (
            ("left", fr["T_world_cam_left"], rig.intrinsics),
            ("right", fr["T_world_cam_right"], rig.right),
        ):
            if board is not None:  # a board's features: points, one id each
                out_[cam] = project_board(
                    np.asarray(T), intr, board[0], board[1],
                    pixel_sigma=s.noise.pixel_sigma, rng=rng,
                )  # fmt: skip
                continue
            if marks is None:  # pragma: no cover - sim_setup gives a field without a board
                raise InternalError("a scenario without a board has no marker field")
            out_[cam] = project_markers(
                np.asarray(T), intr, *marks, pixel_sigma=s.noise.pixel_sigma, rng=rng
            )
        return out_

    if setup.static is not None:
        detect = static_detect(s, still, rng)
    hooks = AcquisitionHooks(
        detect=None if s.noise.render else detect, record_truth=record_truth, finish=finish
    )
    return robot, hooks


def _flange_cameras_only(s: Scenario, setup: SimSetup, what: str) -> None:
    """Refuse an eye-to-hand scenario for ``what`` renders the cameras on the flange: its camera
    stands still and its board rides on the flange, which the flange cameras' scene
    (:class:`selfcal.sim.sim_robot.SimRobot`) does not hold.

    Raises:
        ConfigError: an eye-to-hand scenario, naming its file and ``[camera] setup``.
    """
    if setup.static is not None:
        raise ConfigError(
            f'{s.source}: [camera] setup = "eye-to-hand": {what} renders the cameras on the '
            "flange, and this scenario's camera stands still with the board on the flange",
            fix="simulate it with `selfcal run` or `selfcal acquire` (they render the still "
            "camera), or give a scenario with the camera on the flange",
        )


def make_sim_robot(s: Scenario, setup: SimSetup | None = None):
    """The scenario's simulated actual robot (``selfcal.sim.sim_robot.SimRobot``): actual model, rig,
    marker field, image noise and seeds as the scenario says; the cameras on the flange (an
    eye-to-hand scenario is a :class:`ConfigError`: :func:`open_robot` simulates its still
    camera).
    """
    setup = setup or sim_setup(s)
    _flange_cameras_only(s, setup, "the rendered arm (of `selfcal emulate`, `selfcal diagnose`)")
    check_board_above_table(s, setup)
    rig = setup.rig()
    return SimRobot(
        setup.robot,
        setup.actual,
        rig,
        setup.field,
        image_sigma=s.noise.image_sigma,
        seed=s.noise.seed,
        quantize=s.noise.quantize_joints,
        msaa=s.noise.msaa,
        board=setup.board_pose(),
        compliance=setup.compliance,
    )


def robot_reference(model: str) -> str:
    """What a dataset records as its robot for a scenario's ``[robot] model``: the model name, or
    the robot file's absolute path (a path relative to the working directory would not be found
    from the dataset folder, :attr:`selfcal.io.dataset.Dataset.robot_source`)."""
    path = Path(model)
    return str(path.resolve()) if path.suffix in (".toml", ".urdf") else model


def make_kinematic_robot(s: Scenario, setup: SimSetup | None = None) -> KinematicRobot:
    """The scenario's simulated actual robot for the analytic path
    (:class:`selfcal.sim.kinematic_robot.KinematicRobot`: forward kinematics, no MuJoCo, no images).

    Raises:
        ConfigError: an eye-to-hand scenario (:func:`static_robot` simulates it).
    """
    setup = setup or sim_setup(s)
    _flange_cameras_only(s, setup, "the analytic flange-camera robot")
    rig = setup.rig()
    board = setup.board_pose()
    return KinematicRobot(
        setup.robot, setup.actual, rig, setup.field, quantize=s.noise.quantize_joints,
        board=board, compliance=setup.compliance,
    )  # fmt: skip


def render_posture(
    robot: RobotDef, q: np.ndarray, out: Path, config: str | None = None, model: str | None = None
) -> tuple[Path, ...]:
    """Render the (nominal, unperturbed) robot's cameras at posture ``q`` (rad) into ``out``:
    ``left.png`` and ``right.png``, or ``left.png`` alone for a scenario of one camera
    (``[camera] count = 1``; the simulator renders a pair, the right one is not the scenario's);
    ``model``: what ``robot`` was loaded from (a name or a robot file; default its name).

    Raises:
        ConfigError: an eye-to-hand scenario (its camera is not on the flange).
    """
    s = load_scenario(config, overrides={"robot": {"model": model or robot.name}})
    setup = sim_setup(s)
    _flange_cameras_only(s, setup, "`selfcal render`")
    check_board_above_table(s, setup)
    rig = setup.rig()
    out.mkdir(parents=True, exist_ok=True)
    board = setup.board_pose()
    with SimRobot(robot, None, rig, setup.field, board=board) as sim:
        sim.move_to(np.degrees(q))
        pair = sim.capture()
    paths = (out / "left.png", out / "right.png")[: s.camera.count]
    for p, img in zip(paths, (pair.left, pair.right)):
        write_image_atomic(p, img)
    return paths
