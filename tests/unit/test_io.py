"""The three file formats (dataset.json, calibration.json, truth.json): one writer, one reader.

Round trips are byte-identical (write -> read -> write); a file of another format, of a newer
schema_version, or lacking a key is an InputError naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from selfcal.camera import BrownConrady, Intrinsics
from selfcal.errors import InputError
from selfcal.io.calibration import (
    CalibrationFileError,
    CalibrationResult,
    read_calibration,
    write_calibration,
)
from selfcal.io.dataset_info import (
    DatasetError,
    DatasetInfo,
    read_dataset_info,
    scenario_digest,
    write_dataset_info,
)
from selfcal.io.target_toml import parse_target, target_document
from selfcal.io.truth import (
    TRUTH_JOURNAL,
    Truth,
    TruthFileError,
    append_truth_frame,
    read_truth,
    with_journal,
    write_truth,
)
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.target import Charuco

GOLDEN = Path(__file__).resolve().parents[1] / "golden"


def dataset_info() -> DatasetInfo:
    rng = np.random.default_rng(3)
    return DatasetInfo(
        robot_model="er4u-paper",
        resolution=(640, 480),
        dictionary="DICT_4X4_50",
        scale_ids=(48, 49),
        scale_length_m=0.2037,
        observation="detections",
        planned_joints_deg=np.round(rng.uniform(-90, 90, (7, 5)), 6),
        validation_joints_deg=np.round(rng.uniform(-90, 90, (3, 5)), 6),
        backend="sim",
        provenance={"scenario_sha256": "0" * 64},
        camera_model="opencv",
        camera_free=("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"),
    )


def truth() -> Truth:
    robot = load_robot("er4u-paper")
    nom = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    rng = np.random.default_rng(4)
    act = MCPCModel(nom.params + rng.normal(0, 1e-3, nom.params.shape), nom.joint_types,
                    nom.joint_offsets)  # fmt: skip
    t = Truth(
        robot_model=robot.name,
        joint_names=tuple(robot.joint_names),
        joint_types=nom.joint_types,
        joint_offsets_rad=np.asarray(nom.joint_offsets, float),
        nominal_params=nom.params,
        true_params=act.params,
        intrinsics_left=Intrinsics(800, 1, 319.5, 239.5, 640, 480),  # ints on purpose
        intrinsics_right=BrownConrady(
            801.5, 0.999, 331.5, 231.5, 640, 480, coeffs=(-0.25, 0.1, 1e-3, -5e-4, 0, 0, 0, 0)
        ),
        T_left_right=np.eye(4),
        T_flange_cam=robot.T_flange_cam,
        T_flange_cam_nominal=robot.T_flange_cam,
        T_cam_tip=np.linalg.inv(robot.T_flange_cam),
        marker_field={"dictionary": "DICT_4X4_50", "ids": [1, 2], "size_m": 0.03},
        meta={"seed": np.int64(7), "scale": np.float64(0.25)},
        board={
            "target": target_document(Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")),
            "T_world_board": np.diag([1.0, -1.0, -1.0, 1.0]),
        },
    )
    for k in range(3):
        q = rng.uniform(-1, 1, 5)
        rec = {
            "joints_rad": q,
            "joints_deg": np.degrees(q),
            "T_world_cam_left": np.eye(4),
            "T_world_cam_right": np.eye(4),
            "tool_tip_m": rng.normal(size=3),
        }
        t = t.with_frame(rec, frame_index=k)
    return t


OLDER = Path(__file__).resolve().parents[1] / "data" / "calibration-older.json"
"""The analytic golden calibration.json as written before its keys "warnings", "status",
"failures", the camera model's (#12) and the bounds' camera and pixel_sigma_source (#14) (the
golden file until the simulator read the differential wrist's motors, b64d428): a file of an
older schema."""


def golden_calibration(path: Path = GOLDEN / "analytic" / "calibration.json") -> CalibrationResult:
    doc = json.loads(path.read_text())
    return CalibrationResult.from_json(doc, "golden")


# name -> (value, writer, reader, error kind)
FILES = {
    "dataset.json": (dataset_info, write_dataset_info, read_dataset_info, DatasetError),
    "calibration.json": (golden_calibration, write_calibration, read_calibration,
                         CalibrationFileError),
    "truth.json": (truth, write_truth, read_truth, TruthFileError),
}  # fmt: skip


@pytest.mark.parametrize("name", FILES)
def test_write_read_write_is_byte_identical(tmp_path, name):
    make, write, read, _ = FILES[name]
    a, b = tmp_path / "a" / name, tmp_path / "b" / name
    a.parent.mkdir(), b.parent.mkdir()
    write(a, make())
    write(b, read(a))
    assert a.read_bytes() == b.read_bytes()
    doc = json.loads(a.read_text())
    want = {"dataset.json": 2}.get(name, 1)
    assert doc["schema_version"] == want and list(doc)[:2] == ["format", "schema_version"]


def test_calibration_keeps_every_key_and_number_of_the_golden_file(tmp_path):
    """Reading and writing loses nothing: an older golden document comes back key for key (plus
    the keys this schema adds), every number bit for bit."""
    golden = json.loads(OLDER.read_text())
    path = write_calibration(tmp_path / "calibration.json", golden_calibration(OLDER))
    back = json.loads(path.read_text())
    assert set(back) - set(golden) == {"warnings", "status", "failures"}
    assert back["dataset"].pop("skipped_images") == [] and back.pop("warnings") == []
    assert back.pop("status") == "ok" and back.pop("failures") == []  # #15: a checked result
    added = {"model": "pinhole", "free": ["fx", "mu"], "distortion": {}, "std": {}}
    for doc in (back, *back["methods"].values()):  # the camera model's keys (#12), defaults
        assert {k: doc["intrinsics"].pop(k) for k in added} == added
    assert back["bounds"].pop("camera") == {}
    assert back["bounds"].pop("pixel_sigma_source") == "residuals"  # (#14) an older file's
    assert back == golden


def _valid_doc(tmp_path: Path, name: str) -> dict:
    make, write, _, _ = FILES[name]
    return json.loads(write(tmp_path / name, make()).read_text())


@pytest.mark.parametrize("name", FILES)
def test_a_newer_schema_version_names_the_file_and_the_upgrade(tmp_path, name):
    _, _, read, kind = FILES[name]
    doc = _valid_doc(tmp_path, name)
    doc["schema_version"] = 99
    (tmp_path / name).write_text(json.dumps(doc))
    with pytest.raises(kind, match=f"{name}: schema_version 99 is newer") as err:
        read(tmp_path / name)
    assert isinstance(err.value, InputError) and "upgrade scorbot-selfcal" in str(err.value.fix)


@pytest.mark.parametrize("name", FILES)
def test_an_unknown_format_names_the_file_and_the_key(tmp_path, name):
    _, _, read, kind = FILES[name]
    doc = _valid_doc(tmp_path, name)
    doc["format"] = "something-else"
    (tmp_path / name).write_text(json.dumps(doc))
    with pytest.raises(kind, match=f"{name}: not a .* file \\(format = 'something-else'\\)"):
        read(tmp_path / name)


# a nested key each file cannot do without
MISSING = {
    "dataset.json": ("target", "scale_length_mm"),
    "calibration.json": ("intrinsics", "fx"),
    "truth.json": ("cameras", "T_left_right"),
}


@pytest.mark.parametrize("name", FILES)
def test_a_missing_key_names_the_file_and_the_key(tmp_path, name):
    _, _, read, kind = FILES[name]
    doc = _valid_doc(tmp_path, name)
    outer, inner = MISSING[name]
    del doc[outer][inner]
    (tmp_path / name).write_text(json.dumps(doc))
    with pytest.raises(kind, match=f"{name}: missing key '{outer}.{inner}'") as err:
        read(tmp_path / name)
    assert err.value.fix  # what to do about it


@pytest.mark.parametrize("name", FILES)
def test_malformed_values_and_non_json_are_input_errors(tmp_path, name):
    _, _, read, kind = FILES[name]
    (tmp_path / name).write_text("{not json")
    with pytest.raises(kind, match="not valid JSON"):
        read(tmp_path / name)
    doc = _valid_doc(tmp_path, name)
    doc["schema_version"] = "one"
    (tmp_path / name).write_text(json.dumps(doc))
    with pytest.raises(kind, match="schema_version must be a positive integer"):
        read(tmp_path / name)


def test_files_written_before_schema_version_read_as_version_1(tmp_path):
    """dataset.json and calibration.json used to carry "version": 1, truth.json nothing."""
    for name in FILES:
        doc = _valid_doc(tmp_path, name)
        if name == "dataset.json":
            doc = _dataset_v1(doc)
        del doc["schema_version"]
        if name != "truth.json":
            doc["version"] = 1
        (tmp_path / name).write_text(json.dumps(doc))
        FILES[name][2](tmp_path / name)


def test_calibration_result_gives_the_model_and_si_std():
    res = golden_calibration()
    doc = json.loads((GOLDEN / "analytic" / "calibration.json").read_text())
    np.testing.assert_array_equal(res.model.params, np.asarray(doc["mcpc"]["params_si"]))
    assert res.model.joint_types == tuple(doc["mcpc"]["joint_types"])
    p = doc["parameters"][0]
    assert res.std_si()[p["name"]] == pytest.approx(p["std"] * np.pi / 180, rel=1e-15)
    assert res.pinhole.fx == doc["intrinsics"]["fx"]


def test_calibration_mcpc_shape_is_checked(tmp_path):
    doc = json.loads((GOLDEN / "analytic" / "calibration.json").read_text())
    doc["mcpc"]["params_si"] = doc["mcpc"]["params_si"][:-1]
    (tmp_path / "calibration.json").write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError, match="key 'mcpc.params_si' must be an array"):
        read_calibration(tmp_path)
    with pytest.raises(CalibrationFileError, match="missing"):
        read_calibration(tmp_path / "nowhere")


def test_truth_holds_the_true_board_pose_and_its_target(tmp_path):
    back = read_truth(write_truth(tmp_path / "truth.json", truth()))
    np.testing.assert_array_equal(back.T_world_board, np.diag([1.0, -1.0, -1.0, 1.0]))
    assert back.board is not None
    board = parse_target(back.board["target"], "truth.json")
    assert board == Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100", source="truth.json")


def _dataset_v1(doc: dict) -> dict:
    """A schema-2 dataset.json of the stereo pair and the field as schema 1 wrote it."""
    doc = {**doc, "schema_version": 1}
    cams = doc.pop("cameras")
    doc.pop("image_suffix")
    doc["camera"] = {k: cams[0][k] for k in ("resolution", "model", "free")}
    doc["target"] = {k: v for k, v in doc["target"].items() if k != "type"}
    return doc


def test_dataset_schema_1_reads_as_the_stereo_pair_and_the_field(tmp_path):
    info = dataset_info()
    doc = _dataset_v1(_valid_doc(tmp_path, "dataset.json"))
    (tmp_path / "v1.json").write_text(json.dumps(doc))
    old = read_dataset_info(tmp_path / "v1.json")
    assert old.cameras == ("left", "right") and old.target_type == "field"
    assert old.to_json() == info.to_json()  # rewritten as schema 2, nothing lost


def test_dataset_of_one_camera_and_a_board_round_trips(tmp_path):
    board = {"type": "chessboard", "inner_corners": [11, 8], "square_mm": 15.0}
    info = dataclasses.replace(dataset_info(), cameras=("cam0",), board=board, dictionary="",
                               image_suffix=".jpg")  # fmt: skip
    back = read_dataset_info(write_dataset_info(tmp_path / "dataset.json", info))
    assert back.cameras == ("cam0",) and back.board == board and back.image_suffix == ".jpg"
    assert back.target_type == "chessboard" and back.resolution_of("cam0") == (640, 480)
    doc = json.loads((tmp_path / "dataset.json").read_text())
    assert doc["cameras"] == [{"name": "cam0", "resolution": [640, 480], "model": "opencv",
                               "free": list(info.camera_free)}]  # fmt: skip
    doc["target"]["square_mm"] = -1
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match="bad.json: target.*square_mm"):
        read_dataset_info(tmp_path / "bad.json")


def test_dataset_cameras_of_two_sizes_and_bad_names(tmp_path):
    info = dataclasses.replace(dataset_info(), cameras=("a", "b"),
                               resolutions=((640, 480), (1280, 960)))  # fmt: skip
    back = read_dataset_info(write_dataset_info(tmp_path / "dataset.json", info))
    assert back.resolution_of("b") == (1280, 960) and back.resolution == (640, 480)
    doc = json.loads((tmp_path / "dataset.json").read_text())
    doc["cameras"][1]["name"] = "a/b"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match="bad.json: key 'cameras'"):
        read_dataset_info(tmp_path / "bad.json")


def test_dataset_cameras_of_different_models_are_read_per_camera(tmp_path):
    info = dataclasses.replace(dataset_info(), cameras=("a", "b"))
    doc = json.loads(write_dataset_info(tmp_path / "dataset.json", info).read_text())
    doc["cameras"][1]["model"] = "pinhole"
    doc["cameras"][1]["free"] = ["fx", "mu"]
    (tmp_path / "mixed.json").write_text(json.dumps(doc))
    back = read_dataset_info(tmp_path / "mixed.json")
    assert back.model_of("b") == ("pinhole", ("fx", "mu"))
    assert back.model_of("a") == (info.camera_model, tuple(info.camera_free))


def test_truth_journal_folds_frames_back_and_ignores_a_partial_line(tmp_path):
    """A killed acquisition leaves its frames in the journal: they come back in order, the same
    as recorded one by one, and a half-written last line is dropped."""
    full = truth()
    start = dataclasses.replace(full, frames=full.frames[:1])
    journal = tmp_path / TRUTH_JOURNAL
    for fr in full.frames[1:]:
        append_truth_frame(journal, fr)
    with open(journal, "a") as fh:
        fh.write('{"index": 3, "frame_in')  # killed mid-line
    back = with_journal(start, journal)
    assert [f.to_json() for f in back.frames] == [f.to_json() for f in full.frames]
    assert with_journal(start, tmp_path / "none.jsonl") is start
    journal.write_text("not json\n")
    with pytest.raises(TruthFileError, match="line 1"):
        with_journal(start, journal)


def test_dataset_written_with_the_whole_scenario_reads_and_keeps_only_its_digest(tmp_path):
    """Datasets from before ``provenance`` held the whole scenario (the true camera, the seeds):
    they still read, the scenario is reduced to its digest (what resuming compares), and the
    digest ignores how the hardware is reached."""
    scenario = {"camera": {"fx": 800.0}, "noise": {"seed": 1},
                "robot": {"model": "er4u-paper", "hardware": {"port": "/dev/ttyUSB0"}}}  # fmt: skip
    doc = json.loads(write_dataset_info(tmp_path / "dataset.json", dataset_info()).read_text())
    assert "scenario" not in doc and doc["provenance"] == {"scenario_sha256": "0" * 64}
    del doc["provenance"]
    doc["scenario"] = scenario
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = read_dataset_info(tmp_path / "old.json")
    moved = {**scenario, "robot": {**scenario["robot"], "hardware": {"port": "socket://x:1"}}}
    assert old.provenance == {"scenario_sha256": scenario_digest(moved)}
    assert scenario_digest(scenario) != scenario_digest({**scenario, "noise": {"seed": 2}})
    assert "800" not in json.dumps(old.to_json()["provenance"])


def test_report_json_carries_its_schema_version_and_older_reports_still_read(tmp_path):
    """report.json starts with format and schema_version (in the returned dict too); one written
    before them is read as version 1; a newer one is refused naming the file and the key."""
    from selfcal.io.jsonfile import REPORT_SCHEMA_VERSION, read_report, write_report

    report = {"status": "ok", "failures": [], "schema_version": 7}
    path = write_report(tmp_path / "report.json", report)
    assert list(report)[:2] == ["format", "schema_version"]
    assert report["schema_version"] == REPORT_SCHEMA_VERSION == 1
    assert read_report(path) == report == json.loads(path.read_text())
    older = tmp_path / "older.json"
    older.write_text(json.dumps({"status": "ok", "failures": []}))
    assert read_report(older) == {"status": "ok", "failures": []}
    newer = tmp_path / "newer.json"
    newer.write_text(json.dumps({**report, "schema_version": REPORT_SCHEMA_VERSION + 1}))
    with pytest.raises(InputError, match=f"{newer}: schema_version 2 is newer") as err:
        read_report(newer)
    assert "upgrade scorbot-selfcal" in str(err.value.fix)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"format": "scorbot-selfcal-calibration", "schema_version": 1}))
    with pytest.raises(InputError, match="not a scorbot-selfcal-report file"):
        read_report(other)


def test_the_present_golden_calibration_comes_back_unchanged(tmp_path):
    """The golden document of the present schema is written back exactly as it was read."""
    golden = json.loads((GOLDEN / "analytic" / "calibration.json").read_text())
    path = write_calibration(tmp_path / "calibration.json", golden_calibration())
    assert json.loads(path.read_text()) == golden
