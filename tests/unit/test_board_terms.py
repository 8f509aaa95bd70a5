"""Measurement terms on the board route and on the command line, the fast parts.

- selfcal/calibration/board/terms.py: a term sees the board adjustment's chain (free MCPC
  parameters, zero offsets folded into the shape matrices) as one block of every MCPC parameter;
  the chain is the one the adjustment's poses give, and the wrapped block's Jacobian (chain,
  fixture frame, tip) matches central differences.
- a board calibration.json records the terms' sections after ``sources`` and reads them back as
  their types (selfcal/io/board_calibration.py, selfcal/terms/registry.py).
- ``--term KIND=FILE[,NAME=VALUE ...]`` (selfcal/terms/registry.py term_from_spec): a term of any
  registered kind with its declared options; bad input names the option, file or row and the fix.
"""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.board.terms import POSES, build_terms, chain_values
from selfcal.calibration.routes import read_calibration
from selfcal.camera import Pinhole
from selfcal.cli.main import main
from selfcal.errors import InputError
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.terms.probe import ProbeSection, ProbeTerm
from selfcal.terms.registry import kinds_help, parse_term_spec, term_from_spec
from selfcal.terms.tracker import TrackerTerm


def _poses(rng):
    robot = load_robot("kr6-r900")
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    q = rng.uniform(-1.0, 1.0, (6, model.n))
    free = minimal_indices(model.joint_types)[:14]  # V_0, V_1 and some of V_2, V_3
    poses = KinematicPoses(model, q, free, np.zeros((0, 4, 4)), offset_joints=[0, 2, 4],
                           joint_corrections=True)  # fmt: skip
    p = poses.initial_params() + rng.normal(0.0, 0.01, poses.n_params)
    return robot, poses, q, p


def test_the_chain_block_is_the_adjustments_chain_and_its_derivative():
    rng = np.random.default_rng(0)
    _, poses, q, p = _poses(rng)
    flat, D = chain_values(poses, p)
    same = fk_tool(poses.model.with_params(flat), q)
    np.testing.assert_allclose(same, fk_tool(poses.kinematic_model(p), q), atol=1e-14)
    h = 1e-6
    steps = np.eye(poses.n_params)[: poses.n_kin]
    num = np.stack([(chain_values(poses, p + h * e)[0] - chain_values(poses, p - h * e)[0])
                    / (2 * h) for e in steps], axis=1)  # fmt: skip
    assert np.abs(D - num).max() < 1e-8


def test_a_wrapped_term_block_has_the_jacobian_of_its_residuals():
    rng = np.random.default_rng(1)
    _, poses, q, p = _poses(rng)
    term = ProbeTerm(q, rng.normal(0.0, 0.1, (len(q), 3)), np.arange(len(q)))
    built = build_terms([term], poses, 0.2)
    assert [b.name for b in built.parameters] == ["probe_fixture", "probe_tip"]
    values = {POSES: p, **{b.name: b.value + rng.normal(0.0, 1e-3, b.value.shape)
                           for b in built.parameters}}  # fmt: skip
    block = built.residuals[0]
    ev = block.evaluate(values, True)
    assert {pc.block for pc in ev.pieces} == {POSES, "probe_fixture", "probe_tip"}
    h = 1e-7
    for pc in ev.pieces:
        for c in range(pc.J.shape[2]):
            col = int(pc.cols[0, c])
            up, down = dict(values), dict(values)
            up[pc.block] = values[pc.block] + h * np.eye(len(values[pc.block]))[col]
            down[pc.block] = values[pc.block] - h * np.eye(len(values[pc.block]))[col]
            num = block.evaluate(up, False).residuals - block.evaluate(down, False).residuals
            num /= 2 * h
            assert np.abs(pc.J[:, :, c] - num).max() < 1e-5 * max(1.0, np.abs(num).max())


def _section() -> ProbeSection:
    return ProbeSection(file="touches.csv", touches=30, points=30, sigma_mm=0.02, rms_mm=0.03,
                        max_mm=0.06, tip_mm=(30.0, -20.0, 120.0),
                        T_fixture_world_m=np.eye(4))  # fmt: skip


def test_a_board_calibration_json_records_and_reads_the_terms_sections(tmp_path):
    robot = load_robot("ur5e")
    cam = Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480)
    cal = BoardCalibrationResult(
        robot_model=robot.name, target={"type": "chessboard"}, camera_names=("left",),
        cameras=(cam,), camera_std=({},), model=nominal_mcpc(robot),
        nominal_model=nominal_mcpc(robot), reprojection_rms_px=0.1, frames=8, frames_used=8,
        terms=(_section(),),
    )  # fmt: skip
    path = write_board_calibration(tmp_path / "calibration.json", cal)
    back = read_calibration(path)
    assert isinstance(back, BoardCalibrationResult)
    assert back.to_json()["sources"] == ["images", "probe"]
    sec = back.section("probe")
    assert isinstance(sec, ProbeSection) and sec.to_json() == _section().to_json()
    # without terms the document is as before: no sources
    plain = write_board_calibration(tmp_path / "plain.json", BoardCalibrationResult(
        **{**cal.__dict__, "terms": ()}))  # fmt: skip
    assert "sources" not in plain.read_text()


def _touches_file(tmp_path, robot, bad: str | None = None):
    rows = [",".join([*(f"j{j + 1}" for j in range(robot.n)), "x_mm", "y_mm", "z_mm"])]
    for k in range(4):
        rows.append(",".join(["10"] * robot.n + [str(100 * k), "5", "7"]))
    if bad is not None:
        rows[3] = rows[3].replace("5", bad, 1)
    path = tmp_path / "touches.csv"
    path.write_text("\n".join(rows) + "\n")
    return path


def test_a_term_of_any_registered_kind_from_its_spec(tmp_path):
    robot = load_robot("ur5e")
    path = _touches_file(tmp_path, robot)
    term = term_from_spec(f"probe={path},sigma_mm=0.05", robot, {"joint_units": "deg"})
    assert isinstance(term, ProbeTerm) and term.sigma_m == pytest.approx(5e-5)
    np.testing.assert_allclose(term.q[0], np.radians(10.0))
    assert term.file == str(path) and len(term.points) == 4
    # its own joint_units wins over the command's (10 rad is outside the joints' range)
    with pytest.raises(InputError, match="10 rad is outside joint 1's range"):
        term_from_spec(f"probe={path},joint_units=rad", robot, {"joint_units": "deg"})
    spec = parse_term_spec(f"tracker={path},distances=bar.csv,sigma_deg=0.02")
    assert spec.kind.term is TrackerTerm
    assert spec.options({"joint_units": "deg"})["distances"] == "bar.csv"
    assert "probe=FILE" in kinds_help() and "sigma_mm (mm; default 0.02)" in kinds_help()


@pytest.mark.parametrize(
    ("spec", "said", "fix"),
    [
        ("gauge=x.csv", "no measurement kind 'gauge'", "tracker, probe"),
        ("probe", "KIND=FILE", "--term probe=touches.csv"),
        ("probe=FILE,sigma=0.1", "'sigma=0.1' is no option", "sigma_mm (mm; default 0.02)"),
        ("probe=FILE,sigma_mm=-1", "sigma_mm=-1 is not a number > 0", "in mm"),
        ("probe=FILE,sigma_mm=abc", "sigma_mm=abc is not a number > 0", "in mm"),
        ("probe=FILE,joint_units=grad", "joint_units=grad is not one of deg, rad", "deg"),
        ("probe=FILE,sigma_mm=1,sigma_mm=2", "sigma_mm is given twice", "once"),
        ("probe=missing.csv,joint_units=deg", "missing.csv is not a file", "measurements"),
    ],
)
def test_a_bad_term_spec_names_the_option_and_the_fix(tmp_path, spec, said, fix):
    robot = load_robot("ur5e")
    spec = spec.replace("FILE", str(_touches_file(tmp_path, robot)))
    with pytest.raises(InputError) as info:
        term_from_spec(spec, robot, {"joint_units": "deg"})
    assert said in info.value.message and "--term" in info.value.message
    assert fix in str(info.value.fix)


def test_a_term_needs_its_joint_units_and_a_readable_file(tmp_path):
    robot = load_robot("ur5e")
    with pytest.raises(InputError, match="probe needs joint_units") as info:
        term_from_spec(f"probe={_touches_file(tmp_path, robot)}", robot)
    assert "joint_units=VALUE" in str(info.value.fix)
    bad = _touches_file(tmp_path, robot, bad="five")
    with pytest.raises(InputError) as info:
        term_from_spec(f"probe={bad},joint_units=deg", robot)
    text = str(info.value)
    assert "touches.csv" in text and "row" in text, text


def test_the_command_refuses_a_bad_term_before_any_work(tmp_path, capsys):
    assert main(["calibrate", str(tmp_path), "--term", "gauge=x.csv"]) == 2
    err = capsys.readouterr().err
    assert "no measurement kind 'gauge'" in err and "tracker, probe" in err


def test_the_parameter_pool_offers_what_only_a_term_determines():
    """Images whose first two joints never move cannot tell those joints' parameters apart;
    probe touches over the whole workspace can (selfcal/calibration/board/parameter_pool.py
    with the terms' rows, their own unknowns projected out)."""
    from selfcal.calibration.board.parameter_pool import parameter_pool

    rng = np.random.default_rng(0)
    robot = load_robot("kr6-r900")
    model = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    q = lo + (hi - lo) * (0.3 + 0.4 * rng.random((12, robot.n)))
    q[:, :2] = [0.1, 0.2]  # joints 1 and 2 never move in the images
    qt = lo + (hi - lo) * (0.2 + 0.6 * rng.random((30, robot.n)))
    probe = ProbeTerm(qt, rng.normal(0.0, 0.1, (30, 3)), np.arange(30))
    alone, both = parameter_pool(model, q), parameter_pool(model, q, (probe,))
    gained = {"alpha1", "alpha2", "beta2", "lx1", "lx2", "ly3", "offset_j2", "offset_j3"}
    assert gained <= set(alone.held) and all(alone.held[n].startswith("rank") for n in gained)
    assert not gained & set(both.held) and len(both.order) == len(alone.order) + len(gained)
