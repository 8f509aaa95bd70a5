"""One draw of the board accuracy Monte Carlo (:mod:`selfcal.benchmarks.board.accuracy`, issue
#29): the draw's scenario and simulator, the calibration's deviation prior, and one simulated
board calibration with its predicted against its true flange error over the workspace sample.
"""

from __future__ import annotations

import dataclasses
import tempfile
import warnings
import zlib
from collections.abc import Iterator
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from io import StringIO
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.acquisition.simulator_setup import SimSetup, sim_setup
from selfcal.benchmarks.corner_noise import corner_noise
from selfcal.benchmarks.tracker.accuracy import coverage_if_right
from selfcal.calibration.board.accuracy import (
    board_error_model_from_json,
    board_postures_from_json,
)
from selfcal.calibration.board.deviation import Deviation
from selfcal.config.scenario import Scenario, load_scenario, scenarios_dir
from selfcal.errors import InternalError, UsageError
from selfcal.io.board_calibration import BoardCalibrationResult, read_board_calibration
from selfcal.io.truth import Truth, read_truth
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.kinematics.tool_error import (
    WorkspaceSample,
    joint_spans,
    posture_distance,
    revolute_joints,
    workspace_sample,
)
from selfcal.pipeline.board_run import calibrate_board_run
from selfcal.pipeline.run import run_acquire, run_all
from selfcal.robot.encoder import EncoderSpec
from selfcal.sim.compliance import SHOULDER
from selfcal.sim.gear import draw_gear
from selfcal.transforms import inv_pose

__all__ = [
    "GaussianReadBack",
    "calibrated",
    "calibrated_folder",
    "draw",
    "draw_sample",
    "prior",
    "scenario",
    "simulated",
    "simulated_calibration",
    "true_chain",
    "COUNT",
    "DEFAULT_MODELS",
    "MODELS",
    "POSES",
    "REGIONS",
    "ROBOTS",
    "SCENARIO",
]

ROBOTS = ("er4u-paper", "ur5e", "kr6-r900")
MODELS = ("fits", "compliance", "gear")
DEFAULT_MODELS = ("fits", "compliance")
"""``--models``'s default: the models of the blocks of seeds (the gear's rows have their own,
:data:`selfcal.benchmarks.board.accuracy_tables.BLOCK_GEAR`)."""
POSES = 30
COUNT = 128
REGIONS = ("inside", "edge", "workspace")
SCENARIO = scenarios_dir() / "mono-charuco.toml"


def _angle(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """(m,) deg the rotation angles between (m, 3, 3) rotations."""
    return np.degrees(np.linalg.norm(Rotation.from_matrix(R_a @ np.swapaxes(R_b, 1, 2))
                                     .as_rotvec(), axis=1))  # fmt: skip


def scenario(robot: str, sigma_px: float, seed: int, poses: int = POSES,
             image_sigma: float | None = None, *,
             noise_seed: int | None = None) -> Scenario:  # fmt: skip
    """The draw's scenario: mono-charuco on ``robot`` with its noise, seeds and ``poses``
    calibration postures; analytic with corner noise ``sigma_px``, or with ``image_sigma``
    (grey levels) rendered with that sensor noise and detected (``sigma_px`` then unused);
    ``noise_seed``: the noise's own seed (default ``seed``: a new truth with its own noise;
    another one keeps the truth and postures of ``seed`` and draws new noise)."""
    noise = ({"render": False, "pixel_sigma": sigma_px} if image_sigma is None
             else {"render": True, "image_sigma": image_sigma})  # fmt: skip
    return load_scenario(SCENARIO, {
        "robot": {"model": robot},
        "noise": noise | {"seed": seed if noise_seed is None else noise_seed},
        "trajectory": {"poses": poses, "seed": seed}, "perturbation": {"seed": seed}})  # fmt: skip


def simulated(s: Scenario, model: str) -> SimSetup:
    """The simulator of ``s`` with the model ``model`` (:data:`MODELS`): the scenario's own arm,
    with ``"compliance"`` the same arm bending (:data:`selfcal.sim.compliance.SHOULDER`), with
    ``"gear"`` one of its joints turning through an eccentric gear drawn for the truth's seed
    (:func:`selfcal.sim.gear.draw_gear` on the actual chain; the calibration never sees either)."""
    if model not in MODELS:
        raise UsageError(f"unknown model {model!r}: one of {', '.join(MODELS)}")
    setup = sim_setup(s)
    if model == "fits":
        return setup
    bend = (SHOULDER if model == "compliance"
            else draw_gear(setup.actual, setup.robot.limits, s.perturbation.seed))  # fmt: skip
    return dataclasses.replace(setup, compliance=bend)


def prior(s: Scenario) -> Deviation:
    """The prior on the arm's deviation from its drawing the benchmark gives the calibration
    (``selfcal calibrate --deviation-mm/--deviation-deg``): the simulated arm's own spread,
    ``s``'s ``[perturbation]``, which a user would state for their arm; the calibration itself
    never reads the simulator's perturbation."""
    p = s.perturbation
    return Deviation(p.translation_mm / 1e3, float(np.radians(p.rotation_deg)))


def simulated_calibration(sigma_px: float, seed: int, noise: dict | None = None, *,
                          scenario_file: Path = SCENARIO,
                          robot: str | None = None) -> tuple[BoardCalibrationResult, Truth]:  # fmt: skip
    """One simulated board calibration: ``scenario_file`` (default :data:`SCENARIO`; its
    ``[robot] model`` replaced by ``robot`` when given) on the analytic path with corner noise
    ``sigma_px`` and the draw's ``seed`` (perturbation, :data:`POSES` postures, noise; ``noise``
    more ``[noise]`` keys) acquired and calibrated as ``selfcal run`` does with the deviation
    :func:`prior`, quietly in a temporary folder: its calibration and truth."""
    over = {"noise": {"render": False, "pixel_sigma": sigma_px, "seed": seed} | (noise or {}),
            "trajectory": {"poses": POSES, "seed": seed}, "perturbation": {"seed": seed}}  # fmt: skip
    if robot is not None:
        over["robot"] = {"model": robot}
    with (tempfile.TemporaryDirectory(prefix="selfcal-acc-") as d, warnings.catch_warnings(),
          redirect_stdout(StringIO()), redirect_stderr(StringIO())):  # fmt: skip
        warnings.simplefilter("ignore")
        out = Path(d) / "run"
        s = load_scenario(scenario_file, over)
        run_all(s, out, quiet=True, figures=False, deviation=prior(s))
        return read_board_calibration(out / "calibration.json"), read_truth(out / "truth.json")


class GaussianReadBack(EncoderSpec):
    """The simulated controller's read-back with a Gaussian error of the rounded counts'
    standard deviation (:attr:`EncoderSpec.read_back_sigma`, uncorrelated between joints; the
    same for the same posture) instead of the rounding: ``--read-back gaussian``, to tell the
    rounding's bounded error from the rest of a row's coverage. The calibration still reads
    the robot file's table (the same standard deviation)."""

    def read_back(self, q: np.ndarray) -> np.ndarray:
        """``q`` (rad / m) plus the Gaussian read-back error (class docstring)."""
        q = np.asarray(q, dtype=float)
        rng = np.random.default_rng(zlib.crc32(q.tobytes()))
        return q + rng.standard_normal(q.shape) * self.read_back_sigma


@contextmanager
def calibrated_folder(s: Scenario, setup: SimSetup) -> Iterator[Path]:
    """``s`` acquired with the simulator ``setup`` and calibrated as ``selfcal run`` does with
    the deviation :func:`prior`, quietly, in a temporary folder (its dataset, ``truth.json``
    and ``calibration.json``) that lives as long as the context."""
    with (tempfile.TemporaryDirectory(prefix="selfcal-acc-") as d, warnings.catch_warnings(),
          redirect_stdout(StringIO()), redirect_stderr(StringIO())):  # fmt: skip
        warnings.simplefilter("ignore")
        out = Path(d) / "run"
        run_acquire(s, out, quiet=True, setup=setup)
        calibrate_board_run(out, quiet=True, deviation=prior(s))
        yield out


def calibrated(s: Scenario, setup: SimSetup, *,
               rendered: bool = False) -> tuple[BoardCalibrationResult, Truth, dict | None]:  # fmt: skip
    """``s`` acquired with the simulator ``setup`` and calibrated as ``selfcal run`` does with
    the deviation :func:`prior`, quietly in a temporary folder: its calibration, its truth and,
    ``rendered``, the detector's corner noise
    (:func:`selfcal.benchmarks.corner_noise.corner_noise`; else None)."""
    with calibrated_folder(s, setup) as out:
        cal = read_board_calibration(out / "calibration.json")
        truth = read_truth(out / "truth.json")
        corners = corner_noise(out).to_json() if rendered else None
    if cal.accuracy is None or truth.T_world_board is None:
        raise InternalError("the simulated board calibration wrote no accuracy block or its "
                            "truth no board pose")  # fmt: skip
    return cal, truth, corners


def draw_sample(cal: BoardCalibrationResult, seed: int) -> WorkspaceSample:
    """The draw's workspace sample (:data:`COUNT` joint vectors per region, seeded ``seed + 1``)
    around the calibration postures of ``cal``'s accuracy block."""
    block = cal.accuracy
    assert block is not None
    q_cal = board_postures_from_json(block, cal.model.n, "calibration.json")
    return workspace_sample(q_cal, np.asarray(block["joint_limits_si"]), count=COUNT,
                            seed=seed + 1)  # fmt: skip


def true_chain(cal: BoardCalibrationResult, truth: Truth) -> MCPCModel:
    """The true chain in the board frame with ``cal``'s joint offsets: its minimal parameters
    compare with the calibration's one by one (:func:`selfcal.kinematics.alignment.express_in_frame`)."""
    assert truth.T_world_board is not None
    return express_in_frame(truth.true_model, inv_pose(truth.T_world_board), like=cal.model)


def draw(args: tuple) -> dict:
    """One draw (``robot``, noise ``sigma_px``, ``model``, ``seed``, optionally the calibration
    postures' count, default :data:`POSES`, and the rendered path's image noise, default None:
    analytic, and the simulated read-back, default ``"rounded"``, or ``"gaussian"``:
    :class:`GaussianReadBack`): per region the predicted
    95 % bound with and without the model error, the predicted RMS, the true error (mm), the
    predicted 95 % orientation bound with and without the model error, the true orientation
    error (deg) and whether the calibration says its model error is not measured there (1.0,
    else 0.0: :meth:`selfcal.kinematics.tool_error.ToolErrorModel.unmeasured`, from the
    calibration alone), and its posture distance to the nearest calibration posture
    (:func:`selfcal.kinematics.tool_error.posture_distance` in the unit of
    :func:`selfcal.kinematics.tool_error.joint_spans`); ``measured_to``: the folds' reach (unit-free distance, infinite
    without folds); per region also ``<region>_right``, the coverage a right prediction would
    show there (:func:`selfcal.benchmarks.tracker.accuracy.coverage_if_right`); ``model_error_mm``;
    rendered, the detector's ``corners``
    (:func:`selfcal.benchmarks.corner_noise.corner_noise`); ``status``."""
    robot, sigma_px, model, seed = args[:4]
    poses = int(args[4]) if len(args) > 4 else POSES
    image_sigma = args[5] if len(args) > 5 else None
    read_back = args[6] if len(args) > 6 else "rounded"
    try:
        s = scenario(robot, sigma_px, seed, poses, image_sigma)
        setup = simulated(s, model)
        if read_back == "gaussian" and setup.robot.encoder is not None:
            enc = GaussianReadBack(**{f.name: getattr(setup.robot.encoder, f.name)
                                      for f in dataclasses.fields(EncoderSpec)})  # fmt: skip
            setup = dataclasses.replace(setup, robot=dataclasses.replace(setup.robot, encoder=enc))
        cal, truth, corners = calibrated(s, setup, rendered=image_sigma is not None)
        block = cal.accuracy
        assert block is not None
        em = board_error_model_from_json(block, cal.model, "calibration.json")
        em0 = dataclasses.replace(em, model_error_m=0.0, model_error_rad=0.0)
        sample = draw_sample(cal, seed)
        true_b = true_chain(cal, truth)
        tip = np.asarray(block["T_tool_point_si"])
        bend = (lambda q: q) if setup.compliance is None else setup.compliance.bent
        q_cal = board_postures_from_json(block, cal.model.n, "calibration.json")
        wrap = revolute_joints(cal.model.joint_types)
        span = joint_spans(np.asarray(block["joint_limits_si"]), wrap)
        assert span is not None
        row: dict = {"status": "ok", "corners": corners,
                     "model_error_mm": (block["model_error"] or {}).get("position_mm") or 0.0,
                     "measured_to": float(em.measured_to)}  # fmt: skip
        for name in REGIONS:
            q = getattr(sample, name)
            p = em.predicted(q)
            T_est = fk_tool(cal.model, q) @ tip
            T_true = fk_tool(true_b, bend(q)) @ tip
            row[name] = np.stack([
                p["position_95_mm"], p["estimation_95_mm"], p["position_rms_mm"],
                np.linalg.norm(T_est[:, :3, 3] - T_true[:, :3, 3], axis=1) * 1e3,
                p["orientation_95_deg"], em0.predicted(q)["orientation_95_deg"],
                _angle(T_est[:, :3, :3], T_true[:, :3, :3]), em.unmeasured(q),
                posture_distance(q, q_cal, span, wrap),
            ])  # fmt: skip
            row[f"{name}_right"] = coverage_if_right(em, q, seed)
        return row
    except Exception as exc:  # noqa: BLE001 - a benchmark counts failed draws
        return {"status": f"failed: {type(exc).__name__}: {str(exc)[:200]}"}
