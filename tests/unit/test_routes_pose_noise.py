"""``selfcal.calibrate(root, pose_noise=...)`` reaches a pose dataset's fit as ``--pose-noise``
does, and is refused on a dataset of joint readings (where it would be ignored)."""

from __future__ import annotations

import pytest

from selfcal.calibration import routes
from selfcal.calibration.handeye.eiv import PoseNoise
from selfcal.errors import InputError


@pytest.mark.parametrize("route", ["board", "field"])
def test_pose_noise_on_a_joint_dataset_is_refused(monkeypatch, tmp_path, route):
    monkeypatch.setattr(routes, "dataset_route", lambda root: route)
    with pytest.raises(InputError, match="pose_noise applies to a pose dataset"):
        routes.calibrate(tmp_path, pose_noise="exact", write=False)


@pytest.mark.parametrize(("given", "passed"), [
    (None, "auto"), ("exact", "exact"), (PoseNoise(0.5, 0.05), PoseNoise(0.5, 0.05)),
])  # fmt: skip
def test_pose_noise_reaches_the_pose_fit(monkeypatch, tmp_path, given, passed):
    seen = {}
    monkeypatch.setattr(routes, "dataset_route", lambda root: "handeye")
    monkeypatch.setattr(routes, "calibrate_pose_dataset",
                        lambda root, *, write, pose_noise, camera: seen.update(n=pose_noise, c=camera))  # fmt: skip
    routes.calibrate(tmp_path, pose_noise=given, write=False)
    assert seen == {"n": passed, "c": "auto"}  # the camera by default chosen by the data
