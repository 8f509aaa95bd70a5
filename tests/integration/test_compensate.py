"""IK with the calibrated model moves the ACTUAL (simulated) tool tip onto the target.

Frames: the calibrated model and the simulator's true robot are both expressed in the robot's
base frame built from their own joint axes 1 and 2 (selfcal.export.deploy.deploy_chain), the frame a user
commands in; the true robot's tip there is the ground truth of where a joint command puts the tool.
The paper's Table II positions are commanded with the tool pitch of row 1 held (as
selfcal.pipeline.run._table_ii_postures does) once with the nominal analytic IK and once with
selfcal.export.compensate.compensated_ik.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from selfcal.cli.deploy import register
from selfcal.config.scenario import load_scenario
from selfcal.export.compensate import compensated_ik, solve_compensated, tool_target_residual
from selfcal.export.deploy import deploy, deploy_chain
from selfcal.export.robot_toml import to_toml
from selfcal.io.dataset_info import read_dataset_info
from selfcal.io.truth import read_truth
from selfcal.kinematics.forward import fk_nominal
from selfcal.kinematics.ik import UnreachableError, ik_nearest
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.kinematics.tool_pose import tool_pose
from selfcal.pipeline.run import TABLE_II_MM, run_acquire, run_calibrate
from selfcal.robot.definition import load_robot

ROBOT = load_robot("er4u-paper")
_, PITCH, ROLL = tool_pose(
    fk_nominal(ROBOT, ROBOT.home)[0, -1]
)  # Table II row 1's tool pitch / roll


def _run(tmp_path_factory, name: str, overrides: dict):
    out = tmp_path_factory.mktemp(name) / "ds"
    run_acquire(load_scenario(overrides=overrides), out, quiet=True)
    cal = run_calibrate(out, quiet=True)
    return out, cal, read_truth(out / "truth.json")


@pytest.fixture(scope="module")
def noisy(default_analytic):
    """The paper's setting with analytic corners (0.5 px noise, quantised joints)."""
    out, cal, _, rep = default_analytic
    return out, cal, read_truth(out / "truth.json"), rep


@pytest.fixture(scope="module")
def noise_free(tmp_path_factory):
    nf = {"render": False, "pixel_sigma": 0.0, "quantize_joints": False}
    return _run(tmp_path_factory, "nf", {"noise": nf, "trajectory": {"poses": 12}})


def _table(cal, truth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Actual tool-tip errors (mm) at Table II for nominal and compensated commands, and the
    compensated joints (rad)."""
    dep = deploy(cal)
    actual = deploy_chain(truth.true_model, ROBOT, truth.T_cam_tip)
    targets = TABLE_II_MM / 1000.0
    q_nom = np.array([ik_nearest(ROBOT, p, PITCH, ROLL) for p in targets])
    q_cmp = np.array([compensated_ik(cal, ROBOT, p, PITCH, ROLL) for p in targets])
    # the calibrated chain itself reaches every target to 1e-9 (m, rad)
    res = np.array(
        [tool_target_residual(dep, q, p, PITCH, ROLL)[0] for q, p in zip(q_cmp, targets)]
    )
    assert np.abs(res).max() < 1e-9
    ROBOT.check_joints(q_cmp)
    e_nom = np.linalg.norm(actual.tool_tip(q_nom)[:, :3, 3] - targets, axis=1) * 1000
    e_cmp = np.linalg.norm(actual.tool_tip(q_cmp)[:, :3, 3] - targets, axis=1) * 1000
    return e_nom, e_cmp, q_cmp


def _print(title: str, e_nom: np.ndarray, e_cmp: np.ndarray) -> None:
    print(f"\n{title}\n| pos | target (mm) | nominal IK error (mm) | compensated IK error (mm) |")
    print("|---|---|---|---|")
    for k, (p, a, b) in enumerate(zip(TABLE_II_MM, e_nom, e_cmp)):
        print(f"| {k + 1} | {p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f} | {a:.4f} | {b:.6f} |")


def test_compensation_at_table_ii_positions(noisy):
    out, cal, truth, rep = noisy
    e_nom, e_cmp, _ = _table(cal, truth)
    val = rep["validation"]["tool_tip_error_mm"]
    # the calibrated model's error in the base frame on the held-out validation postures
    qv = np.radians(read_dataset_info(out / "dataset.json").validation_joints_deg)
    dep, actual = deploy(cal), deploy_chain(truth.true_model, ROBOT, truth.T_cam_tip)
    e_val = np.linalg.norm(dep.tool_tip(qv)[:, :3, 3] - actual.tool_tip(qv)[:, :3, 3], axis=1) * 1e3
    _print("Table II, paper scenario (analytic corners, 0.5 px, quantised joints)", e_nom, e_cmp)
    print(
        f"validation: aligned RMS {val['calibrated']['rms']:.4f} / max {val['calibrated']['max']:.4f}"
        f" mm; in the base frame RMS {np.sqrt(np.mean(e_val**2)):.4f} / max {e_val.max():.4f} mm"
    )
    # nominal commands miss by millimetres, compensated ones by the calibration's own error
    assert e_nom.min() > 1.0
    assert e_cmp.max() < 1.5 * e_val.max()
    assert e_cmp.max() < 2.0 * val["calibrated"]["max"]
    assert e_cmp.max() < e_nom.min() / 5


def test_noise_free_calibration_compensates_exactly(noise_free):
    """Without noise the calibration is exact, so the compensated tip lands on the target: this
    pins the frames (base frame, tool tip, joint offsets) end to end."""
    _, cal, truth = noise_free
    e_nom, e_cmp, _ = _table(cal, truth)
    _print("Table II, noise-free calibration", e_nom, e_cmp)
    assert e_nom.min() > 1.0
    assert e_cmp.max() < 1e-4  # mm


def test_nominal_model_gives_the_nominal_ik():
    """With the nominal chain as 'calibration' the result is the analytic IK (to 1e-9 rad)."""
    for p in TABLE_II_MM / 1000.0:
        q = compensated_ik(nominal_mcpc(ROBOT), ROBOT, p, PITCH, ROLL)
        assert np.abs(q - ik_nearest(ROBOT, p, PITCH, ROLL)).max() < 1e-9


def test_unreachable_targets_are_reported(noise_free):
    _, cal, _ = noise_free
    with pytest.raises(UnreachableError, match="out of reach") as exc:
        compensated_ik(cal, ROBOT, np.array([0.9, 0.0, 0.3]), PITCH, ROLL)
    assert exc.value.distance_m > 0.1
    with pytest.raises(ValueError, match="finite 3-vector"):
        compensated_ik(cal, ROBOT, np.array([0.3, np.nan, 0.2]), PITCH, ROLL)
    with pytest.raises(ValueError, match="branch"):
        solve_compensated(cal, ROBOT, TABLE_II_MM[0] / 1000, PITCH, ROLL, branch="sideways")


def test_other_branch_is_followed(noise_free):
    _, cal, _ = noise_free
    p = TABLE_II_MM[0] / 1000
    res = solve_compensated(cal, ROBOT, p, PITCH, ROLL, branch="front/elbow-up")
    assert res.branch == "front/elbow-up"
    assert np.abs(tool_target_residual(deploy(cal), res.joints, p, PITCH, ROLL)).max() < 1e-9
    default = solve_compensated(cal, ROBOT, p, PITCH, ROLL)
    assert np.abs(res.joints - default.joints).max() > 0.1  # a different posture


def _parser(with_nominal_ik: bool):
    p = argparse.ArgumentParser(prog="selfcal")
    sub = p.add_subparsers(dest="command", required=True)
    if with_nominal_ik:  # like selfcal/cli/main.py: an existing `ik` keeps working
        sp = sub.add_parser("ik")
        sp.add_argument("--model", default="er4u-paper")
        sp.add_argument("--xyz", required=True)
        sp.add_argument("--pitch", type=float, required=True)
        sp.add_argument("--roll", type=float, default=0.0)
        sp.add_argument("--branch", default=None)
        sp.set_defaults(func=lambda args: "nominal")
    register(sub)
    return p


@pytest.mark.parametrize("with_nominal_ik", [True, False])
def test_cli_ik_with_calibration(noise_free, capsys, tmp_path, with_nominal_ik):
    out, cal, _ = noise_free
    p = TABLE_II_MM[1]
    argv = ["ik", "--xyz", ",".join(map(str, p)), "--pitch", str(np.degrees(PITCH))]
    argv += ["--roll", str(np.degrees(ROLL))]
    parser = _parser(with_nominal_ik)
    args = parser.parse_args([*argv, "--calibration", str(out / "calibration.json")])
    assert args.func(args) == 0
    got = json.loads(capsys.readouterr().out)
    want = compensated_ik(cal, ROBOT, p / 1000, PITCH, ROLL)
    assert np.allclose(got["joints_deg"], np.degrees(want), atol=1e-5)
    assert np.allclose(
        got["nominal_joints_deg"], np.degrees(ik_nearest(ROBOT, p / 1000, PITCH, ROLL)), atol=1e-5
    )
    if with_nominal_ik:
        args = parser.parse_args(argv)
        assert args.func(args) == "nominal"
    # the exported parameter table gives the same commands

    toml_path = tmp_path / "robot.toml"
    toml_path.write_text(to_toml(deploy(cal), ROBOT))
    args = parser.parse_args([*argv, "--calibration", str(toml_path)])
    assert args.func(args) == 0
    assert np.allclose(
        json.loads(capsys.readouterr().out)["joints_deg"], np.degrees(want), atol=1e-5
    )


def test_cli_ik_unreachable_says_so(noise_free):
    from selfcal.cli.main import CliError

    out, _, _ = noise_free
    args = _parser(True).parse_args(
        ["ik", "--xyz", "900,0,300", "--pitch", "-90", "--calibration", str(out)]
    )
    with pytest.raises(CliError, match="unreachable"):
        args.func(args)
