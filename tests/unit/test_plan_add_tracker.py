"""`selfcal plan --add K DIR` for a tracker calibration (selfcal/calibration/tracker/add.py,
selfcal/cli/plan_tracker_add.py): the added postures are the tracker plan's kind (reachable,
free of collision and the keep-out boxes), their prediction is the tracker plan's own with the
calibration's rows, the outputs, and every refusal names the file and the fix."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from selfcal.benchmarks.plan.tracker import TOOL_POINT_M
from selfcal.benchmarks.plan.tracker_add import SIGMA_M, wrist_rows
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.reference import CLEAR_MARGIN
from selfcal.calibration.tracker.add import plan_tracker_additions, tracker_dataset
from selfcal.calibration.tracker.calibrate import calibrate_tracker
from selfcal.calibration.tracker.calibration_file import write_tracker_calibration
from selfcal.calibration.tracker.plan import (
    TrackerPlanSetup,
    kept_by_rank,
    posture_information,
    predict_tracker,
    workspace_weight,
)
from selfcal.cli.main import main
from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.keep_out import outside_boxes
from selfcal.robot.definition import load_robot
from selfcal.sim.actual import perturb

BOX_MM = "200,-200,0,600,200,300"  # a fixture in front of the UR5e


def _csv(path, q, xyz, quat=None):
    n = q.shape[1]
    header = [f"j{i + 1}" for i in range(n)] + ["x_mm", "y_mm", "z_mm"]
    rows = np.column_stack([np.degrees(q), xyz * 1e3])
    if quat is not None:
        header += ["qw", "qx", "qy", "qz"]
        rows = np.column_stack([rows, quat])
    path.write_text(",".join(header) + "\n" + "".join(",".join(f"{v:.9f}" for v in r) + "\n"
                                                      for r in rows))  # fmt: skip
    return path


def _identify(folder, csv):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the wrist-only rows' rank note
        run = calibrate_tracker(csv, "ur5e", "deg")
    folder.mkdir()
    write_tracker_calibration(folder / "calibration.json", run.calibration)
    return run


@pytest.fixture(scope="module")
def wrist(tmp_path_factory):
    """A UR5e calibration of 12 wrist-only rows (the benchmark's truth 1), its folder."""
    tmp = tmp_path_factory.mktemp("wrist")
    setup = TrackerPlanSetup(load_robot("ur5e"), TOOL_POINT_M)
    true = perturb(setup.model, seed=1, translation_m=1e-3, rotation_rad=np.radians(0.5))
    q = wrist_rows(setup, 1)
    xyz = fk_tool(true, q)[:, :3, 3] + np.random.default_rng(3).normal(0, SIGMA_M, (len(q), 3))
    run = _identify(tmp / "cal", _csv(tmp / "m.csv", q, xyz))
    return tmp / "cal", run


def test_the_added_postures_lower_the_prediction_by_the_tracker_plans_own_criterion(wrist):
    root, run = wrist
    data = tracker_dataset(root, np.array([[0.2, -0.2, 0.0, 0.6, 0.2, 0.3]]))
    assert np.allclose(data.q, run.measurements.q) and data.sigma_source == "calibration"
    assert data.estimated.sum() == run.result.estimated.sum() == 15
    add = plan_tracker_additions(data, 5, seed=1, candidates=200)
    setup = data.setup
    lim = setup.robot.limits
    assert add.q.shape == (5, 6) and np.all((add.q >= lim[:, 0]) & (add.q <= lim[:, 1]))
    assert setup.chain.ok(add.q).all() and outside_boxes(setup.chain, add.q, setup.boxes).all()
    # after: the tracker plan's prediction of the rows and the added postures together
    q_all = np.concatenate([data.q, add.q])
    G = workspace_weight(setup, add.workspace)
    var = Deviation().variance(setup.model.joint_types)
    F = posture_information(setup, q_all).sum(axis=0)
    assert predict_tracker(setup, q_all, F, G, var) == pytest.approx(add.after_m, rel=1e-9)
    assert add.kept_after == kept_by_rank(setup, q_all).sum() > add.kept_before == 15
    # never worse than the pool's first 5 by its own criterion; measured 14.2 times lower
    assert add.after_m <= min(add.random_m, add.greedy_m)
    assert add.before_m / add.after_m >= 4.7
    # the fair nominal of the same rows: the rows and the added postures place the tracker frame
    # and the tool point better, but the chain's deviation stays (measured 3.50 -> 1.84 mm, the
    # calibration after 0.115 times it)
    assert add.fair_after_m < add.fair_before_m and add.after_m < 0.3 * add.fair_after_m


def test_the_command_writes_the_added_postures_and_the_prediction(wrist, tmp_path, capsys):
    root, _ = wrist
    out = tmp_path / "plan"
    argv = ["plan", "--add", "5", str(root), "--candidates", "100", "--keep-out", BOX_MM,
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "plan.json").read_text())
    assert doc["kind"] == "tracker-add" and doc["dataset_rows"] == 12 and doc["count"] == 5
    before, after = doc["predicted_before_tool_rms_mm"], doc["predicted_tool_rms_mm"]
    said = text.split("predicted tool-point error ")[1].split(" mm RMS")[0].split(" -> ")
    assert np.allclose([float(v) for v in said], [before, after], atol=6e-4)
    assert "parameters estimated 15 -> " in text and "the calibration's" in text
    after_line = text.split(
        "\nafter, the fair nominal of the 17 rows (the chain as drawn, the "
        "tracker frame and the tool point fitted) "
    )[1]
    fair, verdict = after_line.split(" mm: ", 1)
    assert float(fair) == pytest.approx(doc["fair_nominal_tool_rms_mm"], abs=6e-4)
    assert (
        verdict.startswith("the calibration is predicted at")
        and doc["clear_margin"] == CLEAR_MARGIN
    )
    q = np.loadtxt(out / "joints.csv", delimiter=",", skiprows=1)
    assert np.allclose(q, doc["joints_deg"], atol=1e-5) and q.shape == (5, 6)
    assert "joint_names:" in (out / "trajectory.yaml").read_text()
    # --sigma-mm overrides the calibration's noise: a noisier tracker predicts more error
    assert main([*argv[:-2], "--sigma-mm", "0.3", "--out", str(tmp_path / "p3")]) == 0
    noisy = json.loads((tmp_path / "p3" / "plan.json").read_text())
    assert noisy["sigma_mm"]["source"] == "given" and noisy["predicted_tool_rms_mm"] > after


def test_bad_input_is_refused_naming_the_file_and_the_fix(wrist, tmp_path, capsys):
    root, run = wrist
    out = ["--out", str(tmp_path / "p")]

    def refused(*argv):
        assert main(["plan", *argv, *out]) == 2
        return capsys.readouterr().err

    err = refused("--add", "0", str(root))
    assert f"--add 0 {root}: add at least 1 posture" in err and "e.g. --add 5" in err
    assert "K must be a whole number" in refused("--add", "two", str(root))
    err = refused("--add", "5", str(root), "--robot", "ur5e", "--tool-point", "0,0,50")
    assert "--robot, --tool-point would not be used" in err and "leave out" in err
    # a dataset of another kind: a folder without a tracker calibration with --measure tracker
    (tmp_path / "board").mkdir()
    (tmp_path / "board" / "calibration.json").write_text('{"format": "other"}')
    err = refused("--measure", "tracker", "--add", "5", str(tmp_path / "board"))
    assert f"{tmp_path / 'board' / 'calibration.json'} is not a tracker calibration" in err
    assert "selfcal identify" in err
    # a calibration of poses: positions are planned
    q = run.measurements.q
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from scipy.spatial.transform import Rotation

        T = fk_tool(run.result.model, q)
        quat = Rotation.from_matrix(T[:, :3, :3]).as_quat()[:, [3, 0, 1, 2]]
    _identify(tmp_path / "poses", _csv(tmp_path / "pm.csv", q, run.measurements.xyz, quat))
    err = refused("--add", "5", str(tmp_path / "poses"))
    assert f"{tmp_path / 'poses' / 'calibration.json'}: a calibration fitted to poses" in err
    assert "identify from the positions alone" in err
    with pytest.raises(InputError, match="no tracker calibration"):
        tracker_dataset(tmp_path / "nothing")
