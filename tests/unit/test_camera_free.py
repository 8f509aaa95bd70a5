"""The configured camera model and free parameters through estimation and files (#12): scenario
keys, dataset.json, calibration.json, and the self-calibration freeing the lens.

The self-calibration tests use synthetic stereo scenes (30 configurations, 0.5 px noise) and
check every free parameter within 3 sigma of truth, sigma from the adjustment's covariance
(measured over 6 seeds: |z| <= 2.6 for the Brown-Conrady lens, <= 1.6 for the fisheye over 4).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from selfcal.calibration.field.calibrate import dataset_camera
from selfcal.calibration.field.self_calibration import self_calibrate
from selfcal.calibration.field.synthetic import synthetic_stereo_scene
from selfcal.camera import BrownConrady, Fisheye, camera_model, canonical_free
from selfcal.config.scenario import ConfigError, load_scenario
from selfcal.importing.dataset import ImportError_, camera_choice
from selfcal.io.calibration_blocks import CameraIntrinsics
from selfcal.io.dataset_info import DatasetError, DatasetInfo
from selfcal.io.jsonfile import Fields

LENS = "k1 = -0.25, k2 = 0.1, p1 = 1e-3, p2 = -5e-4"
FREE = ["fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"]


def _write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_scenario_camera_keys_build_the_true_camera(tmp_path):
    s = load_scenario(_write(tmp_path, f"""[camera]
model = "opencv"
principal_point_offset_px = [12.0, -8.0]
distortion = {{ {LENS} }}
free = {json.dumps(FREE)}
"""))  # fmt: skip
    cam = s.camera.true_model()
    assert isinstance(cam, BrownConrady) and cam.free == tuple(FREE)
    assert (cam.cx, cam.cy) == (331.5, 231.5)
    assert cam.coeffs == (-0.25, 0.1, 1e-3, -5e-4, 0.0, 0.0, 0.0, 0.0)
    default = load_scenario().camera
    assert default.model == "pinhole" and default.free == ["fx", "mu"]
    assert default.true_model().values().tolist() == [800.0, 1.0, 319.5, 239.5, 0.0]  # skew 0


@pytest.mark.parametrize(
    "text, words",
    [
        ('model = "opencv"\ndistortion = { k7 = 0.1 }', ["s.toml", "camera.distortion.k7"]),
        ("distortion = { k1 = 0.1 }", ["camera.distortion.k1", "'pinhole' model"]),
        ('model = "fisheye"\ndistortion = { p1 = 0.1 }', ["camera.distortion.p1"]),
        ('model = "opencv"\ndistortion = { k1 = "big" }', ["camera.distortion.k1", "number"]),
        ('free = ["fx", "k1"]', ["camera.free", "'k1'", "pinhole"]),
        ('free = ["mu"]', ["camera.free", "'fx'"]),
        ('model = "stereographic"', ["camera.model", "stereographic"]),
        ("principal_point_offset_px = [1.0]", ["camera.principal_point_offset_px"]),
        ("lens = 1", ["unknown key 'camera.lens'"]),
        ('free = ["fx", "fy", "mu"]', ["camera.free", "'fy' and 'mu'"]),
    ],
)
def test_bad_camera_keys_name_file_and_key(tmp_path, text, words):
    with pytest.raises(ConfigError) as e:
        load_scenario(_write(tmp_path, f"[camera]\n{text}\n"))
    for w in words:
        assert w in str(e.value)


def test_fy_by_its_opencv_name_frees_the_aspect_ratio(tmp_path):
    """`free = ["fx", "fy", ...]` is the issue's OpenCV form of `["fx", "mu", ...]`: the same
    parametrisation (mu = fy / fx, fx free), in the scenario, camera_model, the import's --free
    and dataset.json; calibration.json reports fy by that name (and mu)."""
    s = load_scenario(_write(tmp_path, '[camera]\nmodel = "opencv"\nfree = ["fx", "fy", "k1"]\n'))
    assert s.camera.free == ["fx", "mu", "k1"] and s.camera.true_model().free == ("fx", "mu", "k1")
    assert canonical_free(["cx", "fy", "fx"]) == ("cx", "mu", "fx")
    with pytest.raises(ValueError, match="'fy' and 'mu'"):
        canonical_free(["fx", "fy", "mu"])
    cam = camera_model("pinhole", fx=800.0, mu=1.01, cx=320.0, cy=240.0, width=640, height=480,
                       free=["fy", "fx"])  # fmt: skip
    assert cam.free == ("fx", "mu")
    assert CameraIntrinsics.of(cam, {"fx": 0.1, "mu": 1e-4}).fy == pytest.approx(808.0)
    assert camera_choice("opencv", ["fx", "fy", "cx", "cy"]) == (
        "opencv",
        ("fx", "mu", "cx", "cy"),
    )
    with pytest.raises(ImportError_, match="'fy' and 'mu'"):
        camera_choice("opencv", ["fx", "fy", "mu"])
    doc = _info(camera_model="opencv", camera_free=("fx", "mu")).to_json()
    for c in doc["cameras"]:
        c["free"] = ["fx", "fy", "k1"]
    assert DatasetInfo.from_json(doc, "dataset.json").camera_free == ("fx", "mu", "k1")
    for c in doc["cameras"]:
        c["free"] = ["fx", "fy", "mu"]
    with pytest.raises(DatasetError, match=r"cameras\[0\]\.free"):
        DatasetInfo.from_json(doc, "dataset.json")


def _info(**kw) -> DatasetInfo:
    return DatasetInfo("er4u-paper", (640, 480), "DICT_4X4_50", (48, 49), 0.2, "detections",
                       np.zeros((6, 5)), np.zeros((0,)), **kw)  # fmt: skip


def test_dataset_names_the_model_and_free_parameters():
    info = _info(camera_model="fisheye", camera_free=("fx", "mu", "k1"))
    doc = info.to_json()
    assert [c.pop("name") for c in doc["cameras"]] == ["left", "right"]  # schema 2: per camera
    assert all(c == {"resolution": [640, 480], "model": "fisheye", "free": ["fx", "mu", "k1"]}
               for c in doc["cameras"])  # fmt: skip
    for c, name in zip(doc["cameras"], ("left", "right")):
        c["name"] = name
    back = DatasetInfo.from_json(doc, "dataset.json")
    assert (back.camera_model, back.camera_free) == ("fisheye", ("fx", "mu", "k1"))
    cam = dataset_camera(back)
    assert isinstance(cam, Fisheye) and cam.free == ("fx", "mu", "k1") and cam.cx == 319.5
    for c in doc["cameras"]:  # an older dataset: the pinhole
        del c["model"], c["free"]
    old = DatasetInfo.from_json(doc, "dataset.json")
    assert (old.camera_model, old.camera_free) == ("pinhole", ("fx", "mu"))
    for c in doc["cameras"]:
        c["free"] = ["fx", "p1"]
    with pytest.raises(DatasetError, match=r"dataset\.json.*cameras\[0\]\.free"):
        DatasetInfo.from_json(doc, "dataset.json")


def test_calibration_block_records_the_camera_by_opencv_names():
    cam = camera_model("opencv", fx=801.0, mu=0.99, cx=331.0, cy=232.0, width=640, height=480,
                       coeffs={"k1": -0.24, "p2": -4e-4}, free=FREE)  # fmt: skip
    std = dict(zip(FREE, np.linspace(0.1, 0.8, 8).tolist()))
    block = CameraIntrinsics.of(cam, std)
    doc = json.loads(json.dumps(block.to_json()))
    assert doc["model"] == "opencv" and doc["free"] == FREE and doc["std"] == std
    assert doc["distortion"]["k1"] == -0.24 and doc["fy"] == pytest.approx(801.0 * 0.99)
    assert list(doc["distortion"]) == ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
    back = CameraIntrinsics.from_json(Fields(doc, "calibration.json", "fix"))
    assert back == block and back.camera() == cam
    skewed = camera_model("pinhole", fx=801.0, mu=0.99, cx=331.0, cy=232.0, width=640,
                          height=480, free=["fx", "mu", "skew"], skew=0.75)  # fmt: skip
    doc = json.loads(json.dumps(CameraIntrinsics.of(skewed, {}).to_json()))
    assert doc["skew"] == 0.75 and "skew" not in doc["distortion"]
    assert CameraIntrinsics.from_json(Fields(doc, "calibration.json", "fix")).camera() == skewed
    del doc["skew"]  # a file written before the skew: 0
    assert CameraIntrinsics.from_json(Fields(doc, "calibration.json", "fix")).skew == 0.0


@pytest.mark.slow  # 13-16 s each; the lens acceptance tests cover the same path end to end
@pytest.mark.parametrize(
    "model, fx, coeffs, free, seed",
    [
        ("opencv", 800.0, {"k1": -0.25, "k2": 0.1, "p1": 1e-3, "p2": -5e-4}, FREE, 3),
        ("fisheye", 500.0, {"k1": 0.05, "k2": -0.02}, FREE[:6], 1),
    ],
)
def test_self_calibration_frees_the_configured_lens(model, fx, coeffs, free, seed):
    truth = camera_model(model, fx=fx, mu=1.0, cx=331.5, cy=231.5, width=640, height=480,
                         coeffs=coeffs, free=free)  # fmt: skip
    start = camera_model(model, fx=1.0, mu=1.0, cx=319.5, cy=239.5, width=640, height=480,
                         free=free)  # fmt: skip
    sc = synthetic_stereo_scene(30, seed=seed, noise_px=0.5, camera=truth)
    res = self_calibrate(sc.observations(), 640, 480, scale_markers=sc.scale_markers,
                         scale_distance_m=sc.scale_distance_m, camera=start)  # fmt: skip
    assert type(res.camera) is type(truth) and res.camera.free == truth.free
    z = (res.camera.free_values() - truth.free_values()) / np.sqrt(np.diag(res.cov_fx_mu))
    assert np.all(np.abs(z) < 3.0), dict(zip(free, z.round(2)))
    assert set(res.camera_std) == set(free) | {"fy"} and res.rms_px < 0.5 * np.sqrt(2) * 1.1


def test_fy_has_a_standard_deviation_beside_fx_and_mu():
    """OpenCV's fy = mu fx gets its first-order std from the covariance of fx and mu (the
    parameters estimated), for one camera and for each camera of a set."""
    from selfcal.camera import CameraSet, Pinhole
    from selfcal.camera.camera_set import free_std

    cam = Pinhole(800.0, 1.002, 320.0, 240.0, 640, 480, ("fx", "mu", "cx"))
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 3))
    cov = A @ A.T * np.array([0.5, 1e-4, 0.3])[:, None] * np.array([0.5, 1e-4, 0.3])[None, :]
    std, per = free_std(cam, cov)
    J = np.array([cam.mu, cam.fx, 0.0])  # d fy / d (fx, mu, cx)
    assert per is None and std["fy"] == pytest.approx(np.sqrt(J @ cov @ J), rel=1e-12)
    assert std["fx"] == pytest.approx(np.sqrt(cov[0, 0])) and set(std) == {"fx", "mu", "cx", "fy"}
    draws = rng.multivariate_normal([cam.fx, cam.mu, cam.cx], cov, size=200_000)
    assert np.std(draws[:, 0] * draws[:, 1]) == pytest.approx(std["fy"], rel=0.01)
    right = Pinhole(810.0, 1.0, 330.0, 250.0, 640, 480, ("fx", "cx"))
    pair = CameraSet((cam, right), ("left", "right"))
    big = np.zeros((5, 5))
    big[:3, :3], big[3:, 3:] = cov, cov[[0, 2]][:, [0, 2]]
    _, per = free_std(pair, big)
    assert per["left"]["fy"] == pytest.approx(std["fy"])
    assert per["right"]["fy"] == pytest.approx(right.mu * per["right"]["fx"])  # mu held


def test_a_camera_info_with_skew_starts_the_camera_with_it():
    """K[0, 1] of a calibrated CameraInfo is the initial camera's skew (it was dropped)."""
    from selfcal.ros.bag_import import initial_values
    from selfcal.ros.rosbag import CameraInfo

    K = (800.0, 1.5, 321.0, 0.0, 802.0, 239.0, 0.0, 0.0, 1.0)
    info = CameraInfo(640, 480, "plumb_bob", (-0.2, 0.05, 0.0, 0.0, 0.0), K)
    values = initial_values(info, "opencv")
    assert values["skew"] == 1.5 and values["k1"] == -0.2
    start = {"source": "camera_info", "where": "x.bag#/info", "values": values}
    cam = _info(camera_model="opencv", camera_free=("fx", "mu", "skew"),
                camera_initial=(start, None)).initial_camera("left")  # fmt: skip
    assert cam.skew == 1.5 and cam.K[0, 1] == 1.5 and cam.fx == 800.0
    plain = initial_values(
        CameraInfo(640, 480, "plumb_bob", (0.0,) * 5, (800.0, 0.0, *K[2:])), "opencv"
    )
    assert "skew" not in plain  # a camera without skew: the file stays as it was
