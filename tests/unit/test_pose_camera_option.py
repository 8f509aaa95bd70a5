"""``selfcal calibrate DIR --camera auto|held|refined`` and ``selfcal.calibrate(dir, camera=...)``
reach a pose dataset's hand-eye fit, calibration.json's ``camera_choice`` says the caller forced
the treatment, and both are refused on a dataset of joint readings (where they would be
ignored). The dataset on disk is real; its corners are simulated (the images' detection is
:func:`selfcal.calibration.routes.pose_features`'s, tested with the board route)."""

from __future__ import annotations

import json

import pytest

from selfcal.calibration import routes
from selfcal.calibration.handeye.calibrate import chain_motions
from selfcal.calibration.handeye.eiv import EXACT
from selfcal.cli.main import main
from selfcal.errors import InputError, UsageError
from selfcal.io.poses.dataset import PoseDataset, write_pose_dataset
from tests.unit.test_handeye import BOARD, _features, _scene

SETUP = "eye-to-hand"


@pytest.fixture
def pose_dir(tmp_path, monkeypatch):
    """A pose dataset (dataset.json, poses.csv) whose board sees 10 noisy views."""
    X, B, F = _scene(SETUP, 10, seed=4)
    feats = _features(X, B, chain_motions(SETUP, F), 0.3, 6)
    write_pose_dataset(PoseDataset(root=tmp_path, setup=SETUP, camera="cam", resolution=(1280, 960),
                                   model="opencv", free=("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"),
                                   board={}, T_base_flange=F))  # fmt: skip
    monkeypatch.setattr(routes, "pose_features", lambda ds: (BOARD, feats))
    return tmp_path


def _camera_choice(root) -> dict:
    return json.loads((root / "calibration.json").read_text())["camera_choice"]


@pytest.mark.parametrize("camera", ["held", "refined"])
def test_the_api_forces_the_camera_and_records_it(pose_dir, camera):
    cal = routes.calibrate(pose_dir, camera=camera, pose_noise="exact")  # as docs/api.md says
    assert cal.nominal.pose_noise == EXACT
    assert cal.camera_refined == (camera == "refined")
    assert (cal.calibrated is cal.nominal) == (camera == "held")
    assert cal.camera_choice is None  # no cross-validation ran
    assert _camera_choice(pose_dir) == {"treatment": camera, "chosen_by": "caller",
                                        "cross_validation": None}  # fmt: skip


def test_the_cli_forces_the_camera(pose_dir, capsys):
    assert main(["calibrate", str(pose_dir), "--camera", "refined", "--pose-noise", "exact"]) == 0
    assert _camera_choice(pose_dir)["treatment"] == "refined"
    assert "camera: refined with the hand-eye (as asked)" in capsys.readouterr().err


def test_a_bad_camera_is_refused_before_the_detection(monkeypatch, tmp_path):
    monkeypatch.setattr(routes, "dataset_route", lambda root: "handeye")
    with pytest.raises(UsageError, match="camera 'free': give one of auto, held, refined"):
        routes.calibrate(tmp_path, camera="free")  # tmp_path holds no dataset: not opened
    assert main(["calibrate", str(tmp_path), "--camera", "free"]) == 2  # argparse's choices


@pytest.mark.parametrize("route", ["board", "field"])
def test_camera_on_a_joint_dataset_is_refused(monkeypatch, tmp_path, capsys, route):
    monkeypatch.setattr(routes, "dataset_route", lambda root: route)
    with pytest.raises(InputError, match=r"camera \(held or refined\) applies to a pose dataset"):
        routes.calibrate(tmp_path, camera="held", write=False)
    assert main(["calibrate", str(tmp_path), "--camera", "auto"]) == 2
    err = capsys.readouterr().err
    assert "--camera (held or refined) applies to a pose dataset's hand-eye" in err
    assert "leave --camera out" in err
    assert not (tmp_path / "calibration.json").exists()


def test_a_term_on_a_pose_dataset_is_refused_for_the_dataset_not_its_options(pose_dir, capsys):
    """--term on a pose dataset says the dataset takes no terms, before the term's own options
    (a probe without --joint-units said "needs joint_units", which adding would not fix)."""
    assert main(["calibrate", str(pose_dir), "--term", "probe=touches.csv"]) == 2
    err = capsys.readouterr().err
    assert "is a pose dataset" in err and "joint_units" not in err
    assert not (pose_dir / "calibration.json").exists()
