"""The real-data tier (``uv run pytest -m real``; ``.ci/run`` runs it after the slow tier).

Each real set of ``tests/data/real/`` (README.md there: source, licence, what was copied) goes
through the documented commands as a user types them: ``selfcal import`` of the calibration
split and of the held-out split, ``selfcal calibrate`` and ``selfcal evaluate --out``, each a
subprocess in a temporary folder (so a ``runs/`` folder of an earlier ``selfcal run`` changes
nothing). Asserted per set:

- the images ``import`` keeps are those OpenCV's own detectors find (computed here, on the
  same files: ``findChessboardCorners``, else ``findChessboardCornersSB``; ``CharucoDetector``);
- the held-out reprojection RMS of the calibrated model is at most 1.1x the independent
  reference's held-out figure (``reference.toml``: the best of its nominal and calibrated);
- the calibrated model beats the nominal one on the held-out images, as ``evaluate`` reports both;
- ``evaluate``'s nominal is the fair one: at most 1.5x the reference's held-out nominal (the
  nominal chain with hand-eye and board pose fitted on the pixels), so that beating it means
  something;
- ``selfcal check`` finds the Nachi sets' held-out group (same session, unchanged arm) unchanged,
  and changed against the calibration with a small lens change (k3) written into its file;
- issue #29: the held-out reprojection RMS the board calibration predicts is within 0.67-1.5x
  the one ``evaluate`` measures, as ``uv run python -m selfcal.benchmarks.board.accuracy --real``
  reports it (docs/tool-accuracy.md), on the splits the commands above imported.

What fails today is marked ``xfail(strict=True)`` with the figure measured, so the tier stays
green and turns red (XPASS) the moment a fix lands: then the mark goes.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np
import pytest

from selfcal.benchmarks.board.accuracy import REAL_SETS, real_set
from selfcal.calibration.board.evaluate import SAME_RMS
from selfcal.calibration.board.plan.add_ground import SCALE_RANGE
from selfcal.io.plan_files import read_plan
from selfcal.tomlfile import read_toml

pytestmark = pytest.mark.real

DATA = Path(__file__).resolve().parents[1] / "data" / "real"
SPLITS = ("calib", "held")
NOMINAL_FAIR_FACTOR = 1.5  # evaluate's nominal against the reference's held-out nominal
REFERENCE_FACTOR = 1.1  # held-out calibrated against the reference's best held-out figure
CHARUCO_MIN_CORNERS = 6  # a ChArUco view counts with 6 corners (reference.py's and import's rule)
# the lens change (k3, held at 0) the drift check must find in a set's held-out group
# (docs/real-data.md): 0.1 on both, p = 0.0042 / 0.0024 (photoneo / mecheye); mecheye's was 0.15
# with the jitter's mean carried (0.1 at the edge: p = 0.0084), and with the bounds' corner noise
# beside the jitter neither was found (0.1 / 0.15: p = 0.046 / 0.69)
AFTER_OF_NOMINAL = 0.4  # plan --add 5's prediction / its fair nominal: 0.17, 0.21 (0.1 mm)
PREDICTED_BAND = (0.67, 1.5)  # issue #29's band of predicted / measured held-out RMS
LENS_K3 = {"nachi-2025-01-17-photoneo": 0.5, "nachi-2025-02-05-mecheye": 0.5}


@dataclass(frozen=True)
class RealSet:
    """One set's documented commands: paths relative to its folder under tests/data/real/."""

    name: str
    robot: str
    images: dict[str, str]  # split -> glob
    joints: dict[str, str]  # split -> joints CSV
    kinematics: bool = True  # False: poses, nothing kinematic to identify

    @property
    def root(self) -> Path:
        return DATA / self.name

    def reference(self) -> dict:
        """The reference's proposed split (reference.toml, from reference-output.txt)."""
        doc = read_toml(self.root / "reference.toml")
        (split,) = [s for s in doc["split"] if s["proposed"]]
        return split


def _nachi(name: str, session: str) -> RealSet:
    im = f"handeye_data/{session}"
    return RealSet(
        name,
        "inputs/nachi_mz25.urdf",
        {"calib": f"{im}/group[1-5]/*.png", "held": f"{im}/group6/*.png"},
        {"calib": "inputs/joints_calib.csv", "held": "inputs/joints_heldout.csv"},
    )


PHOTONEO = "nachi-2025-01-17-photoneo"
MECHEYE = "nachi-2025-02-05-mecheye"
ICAL = "ical-charuco"
SETS = {
    PHOTONEO: _nachi(PHOTONEO, "2025-01-17_data_photoneo"),
    MECHEYE: _nachi(MECHEYE, "2025-02-05_data_mecheye"),
    # eye-to-hand (static camera, board on the wrist, flange poses) written as a virtual 3P+3R
    # chain whose base is the wrist: the only command path that exists until eye-to-hand does
    ICAL: RealSet(
        ICAL,
        "inputs/virtual_inverse_pose_chain_xyz.urdf",
        {"calib": "inputs/images_calib/*.png", "held": "inputs/images_heldout/*.png"},
        {"calib": "inputs/joints_calib.csv", "held": "inputs/joints_heldout.csv"},
        kinematics=False,
    ),
}

# What fails today, measured by this tier (docs/real-data.md): (test, set) -> reason.

_MECHEYE = (
    "the cross-validation over the 5 arm configurations supports no kinematic parameter (joint "
    "offsets 1.267 px against the nominal's 1.256 px): the calibration is the fair nominal, "
    "held-out 1.067 px (NO GAIN) against the reference's 0.615 px with offsets j2..j5, whose own "
    "leave-group-2-out is worse than nominal (4.19 against 0.88 px)"
)
XFAIL = {
    ("reference", MECHEYE): _MECHEYE,
    ("beats_nominal", MECHEYE): _MECHEYE,
}


def cases(test: str) -> list:
    """The sets as parameters, with the xfail mark of XFAIL where ``test`` fails on it today."""
    return [
        pytest.param(
            name, id=name, marks=[pytest.mark.xfail(strict=True, reason=XFAIL[(test, name)])]
        )
        if (test, name) in XFAIL
        else pytest.param(name, id=name)
        for name in SETS
    ]


# ------------------------------------------------------------------ running the commands
def _selfcal_exe() -> str:
    local = Path(sys.executable).with_name("selfcal")
    found = str(local) if local.is_file() else shutil.which("selfcal")
    assert found, "the selfcal command is not installed in this environment (uv sync)"
    return found


@dataclass
class Step:
    """One command: its argv, exit code and output."""

    argv: list[str]
    returncode: int
    output: str

    def __str__(self) -> str:
        tail = self.output.strip()[-600:]
        return f"`selfcal {' '.join(self.argv)}` exited {self.returncode}: ...{tail}"


@dataclass
class Outcome:
    """A set's run through import (both splits), calibrate and evaluate; a step whose input
    failed is not run (None)."""

    imports: dict[str, Step] = field(default_factory=dict)
    # split -> the images imported, relative to the set's folder
    kept: dict[str, list[str]] = field(default_factory=dict)
    calibrate: Step | None = None
    evaluate: Step | None = None
    evaluation: dict | None = None

    @classmethod
    def from_dict(cls, d: dict) -> Outcome:
        """The Outcome ``dataclasses.asdict`` wrote."""
        step = lambda s: Step(**s) if s else None  # noqa: E731
        return cls(
            {k: Step(**v) for k, v in d["imports"].items()},
            d["kept"],
            step(d["calibrate"]),
            step(d["evaluate"]),
            d["evaluation"],
        )

    def held_out_rms(self) -> dict[str, float]:
        """evaluate's held-out reprojection RMS (px) by model, or an assertion naming the step
        that failed."""
        for step in (*self.imports.values(), self.calibrate, self.evaluate):
            assert step is not None and step.returncode == 0, str(step) if step else "not run"
        assert self.evaluation is not None
        return self.evaluation["reprojection_rms_px"]


def run(real: RealSet, out: Path) -> Outcome:
    exe, res = _selfcal_exe(), Outcome()
    target = str(real.root / "inputs" / "target.toml")

    def selfcal(*argv: str) -> Step:
        p = subprocess.run(
            [exe, *argv], cwd=out, capture_output=True, text=True, timeout=1200, check=False
        )
        return Step(list(argv), p.returncode, p.stdout + p.stderr)

    for split in SPLITS:
        ds = out / split
        res.imports[split] = step = selfcal(
            "import", "--robot", str(real.root / real.robot),
            "--images", f"cam0={real.root / real.images[split]}",
            "--joints", str(real.root / real.joints[split]), "--joint-units", "rad",
            "--target", target, "--out", str(ds),
        )  # fmt: skip
        if step.returncode == 0:
            lines = (ds / "sources.csv").read_text().splitlines()[1:]
            files = (Path(line.split(",", 2)[2]) for line in lines)
            res.kept[split] = sorted(
                str(f.resolve().relative_to(real.root.resolve())) for f in files
            )
    if res.imports["calib"].returncode == 0:
        res.calibrate = selfcal("calibrate", str(out / "calib"))
    if res.calibrate and res.calibrate.returncode == 0 and res.imports["held"].returncode == 0:
        ev = out / "calib" / "evaluation.json"  # beside the calibration, as the READMEs write it
        res.evaluate = selfcal("evaluate", str(out / "calib"), str(out / "held"), "--out", str(ev))
        if res.evaluate.returncode == 0:
            res.evaluation = json.loads(ev.read_text())
    return res


@pytest.fixture(scope="session")
def runs_dir(tmp_path_factory: pytest.TempPathFactory, testrun_uid: str) -> Path:
    """One folder for this test run, shared by its xdist workers."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # pytest-N/, beside each worker's popen-gwK/
    out = base / f"real-{testrun_uid}"
    out.mkdir(exist_ok=True)
    return out


@pytest.fixture
def outcome(request: pytest.FixtureRequest, runs_dir: Path) -> Outcome:
    """The set's Outcome: the commands run once per test run, whichever worker asks first (the
    others wait for it on a lock and read its outcome.json)."""
    name = request.node.callspec.params["name"]
    with open(runs_dir / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        done = runs_dir / name / "outcome.json"
        if not done.exists():
            (runs_dir / name).mkdir()
            res = run(SETS[name], runs_dir / name)
            done.write_text(json.dumps(asdict(res)))
        return Outcome.from_dict(json.loads(done.read_text()))


# ------------------------------------------------------------------ OpenCV's own count
def opencv_finds(real: RealSet, split: str) -> list[str]:
    """The image files of ``split`` in which OpenCV's detectors find the board of the set's
    target.toml: a chessboard by ``findChessboardCorners`` or else ``findChessboardCornersSB``,
    a ChArUco board with at least CHARUCO_MIN_CORNERS corners by ``CharucoDetector``."""
    tgt = read_toml(real.root / "inputs" / "target.toml")
    cols, rows = tgt["inner_corners"]
    if tgt["type"] == "charuco":
        board = cv2.aruco.CharucoBoard(
            (cols + 1, rows + 1),
            tgt["square_mm"] / 1000.0,
            tgt["marker_mm"] / 1000.0,
            cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, tgt["dictionary"])),
        )
        detector = cv2.aruco.CharucoDetector(board)

        def found(gray: np.ndarray) -> bool:
            _, ids, _, _ = detector.detectBoard(gray)
            return ids is not None and len(ids) >= CHARUCO_MIN_CORNERS
    else:
        assert tgt["type"] == "chessboard", tgt["type"]

        def found(gray: np.ndarray) -> bool:
            flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
            if cv2.findChessboardCorners(gray, (cols, rows), flags=flags)[0]:
                return True
            flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
            return bool(cv2.findChessboardCornersSB(gray, (cols, rows), flags=flags)[0])

    files = sorted(real.root.glob(real.images[split]))
    assert files, f"no image matches {real.images[split]} in {real.root}"
    gray = (cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files)
    return sorted(
        str(f.resolve().relative_to(real.root.resolve())) for f, g in zip(files, gray) if found(g)
    )


# ------------------------------------------------------------------ the tests
@pytest.mark.parametrize("name", cases("found"))
def test_import_keeps_every_image_opencv_finds(name, outcome):
    real = SETS[name]
    cv = {split: opencv_finds(real, split) for split in SPLITS}
    kept = {split: outcome.kept.get(split, []) for split in SPLITS}  # none where import failed
    differ = [  # the project may keep more (ChArUco: OpenCV's refined marker search), never less
        f"{s}: import keeps {len(kept[s])} images, OpenCV finds the board in {len(cv[s])}; "
        f"only OpenCV: {sorted(set(cv[s]) - set(kept[s]))}, only import: "
        f"{sorted(set(kept[s]) - set(cv[s]))}; {outcome.imports[s]}"
        for s in SPLITS
        if set(cv[s]) - set(kept[s])
    ]
    assert not differ, f"{name}: " + "\n".join(differ)


@pytest.mark.parametrize("name", cases("reference"))
def test_held_out_error_within_1p1_of_the_reference(name, outcome):
    ref = SETS[name].reference()
    best = min(ref["held_out_nominal_px"], ref["held_out_calibrated_px"])
    rms = outcome.held_out_rms()
    assert rms["calibrated"] <= REFERENCE_FACTOR * best, (
        f"{name}: held-out calibrated {rms['calibrated']:.3f} px, reference {best:.3f} px"
    )


@pytest.mark.parametrize("name", cases("beats_nominal"))
def test_held_out_error_below_the_nominal(name, outcome):
    rms = outcome.held_out_rms()
    msg = f"{name}: held-out nominal {rms['nominal']:.3f} px, calibrated {rms['calibrated']:.3f} px"
    same = rms["nominal"] * SAME_RMS  # evaluate's own "the same figure" (NO GAIN)
    if SETS[name].kinematics:
        assert rms["calibrated"] < rms["nominal"] - same, msg
    else:  # poses: nothing kinematic to identify, the nominal model may be the result
        assert rms["calibrated"] <= rms["nominal"] + same, msg


@pytest.mark.parametrize("name", cases("predicted_held_out"))
def test_the_predicted_held_out_error_is_the_measured_one(name, outcome, runs_dir, tmp_path):
    """Issue #29: the held-out RMS the board calibration predicts (the estimate's errors, the
    model error from its own cross-validation, the joint and pixel noise) within
    PREDICTED_BAND of the measured one; :func:`real_set` calibrates the splits this run's
    `selfcal import` wrote (copied, not imported again). Photoneo's 1.63x (the pooled model
    error) is 1.47x since the folds count the share of the held parameters' deviation they
    show, at its upper 95 % bound (docs/tool-accuracy.md)."""
    assert set(REAL_SETS) == set(SETS)  # the benchmark's sets are this tier's
    for step in outcome.imports.values():
        assert step.returncode == 0, str(step)
    r = real_set(name, tmp_path, (runs_dir / name / "calib", runs_dir / name / "held"))
    ratio = r["predicted_px"] / r["measured_px"]
    assert PREDICTED_BAND[0] <= ratio <= PREDICTED_BAND[1], (ratio, r)


@pytest.mark.parametrize("name", cases("fair_nominal"))
def test_evaluate_nominal_is_the_fair_one(name, outcome):
    ref = SETS[name].reference()["held_out_nominal_px"]
    rms = outcome.held_out_rms()
    assert rms["nominal"] <= NOMINAL_FAIR_FACTOR * ref, (
        f"{name}: evaluate's held-out nominal {rms['nominal']:.3f} px, the reference's (nominal "
        f"chain, hand-eye and board pose fitted on the pixels) {ref:.3f} px"
    )


@pytest.mark.parametrize("name", [pytest.param(PHOTONEO, id=PHOTONEO)])
@pytest.mark.parametrize("deviation", [(), ("--deviation-mm", "0.1", "--deviation-deg", "0.05")],
                         ids=["default-deviation", "small-deviation"])  # fmt: skip
def test_plan_add_five_postures_to_the_calibrated_set(name, deviation, outcome, runs_dir):
    """`selfcal plan --add 5` on the calibrated groups 1-5 (docs/plan.md quotes the lines):
    the predicted tool-point error falls at least 2x and more parameters are kept, with the
    deviation from the drawing sized from the calibration's folds (the default: the forecast's
    fair-nominal folds at the misfit they measured) and with one given, 0.1 mm and 0.05 deg;
    the workspace is the dataset's region (the URDF has no planning window)."""
    from selfcal.robot.definition import load_robot

    outcome.held_out_rms()  # import and calibrate ran
    real = SETS[name]
    out = runs_dir / name / f"add5{''.join(deviation)}"
    argv = ["plan", "--add", "5", str(runs_dir / name / "calib"), "--out", str(out), *deviation]
    p = subprocess.run([_selfcal_exe(), *argv], capture_output=True, text=True, timeout=1200,
                       check=False)  # fmt: skip
    assert p.returncode == 0, p.stdout + p.stderr
    doc = read_plan(out / "plan.json")
    gain = doc["predicted_before_tool_rms_mm"] / doc["predicted_tool_rms_mm"]
    assert gain >= 2.0, doc  # measured GAIN_NOTE
    # beyond the placement, as calibrate counts them: 18, 4 (30, 16 with the placement's 12)
    assert doc["kinematic_parameters_after"] > doc["kinematic_parameters_before"]
    assert doc["workspace"]["source"] == "dataset region", doc["workspace"]
    dev = doc["deviation"]
    if deviation:
        assert dev["source"] == "given", dev
    else:  # sized: the forecast's fair-nominal folds at the misfit the calibration measured
        folds = json.loads((runs_dir / name / "calib/calibration.json").read_text())
        measured = np.array(folds["selection"]["candidates"][0]["fold_rms_px"])
        assert dev["source"] == "sized" and dev["folds"] == len(measured), dev
        rms = float(np.sqrt(np.mean(measured**2)))
        # the scale solves forecast(s) = measured in closed form: the match is the check of that
        # arithmetic, and it only means "sized from the data" when the scale was not clipped
        assert SCALE_RANGE[0] < dev["scale_of_default"] < SCALE_RANGE[1], dev
        assert abs(dev["nominal_folds_forecast_px"] - rms) < 1e-3, dev
        assert dev["nominal_folds_forecast_at_default_px"] > 5 * rms, dev  # 23.9 px, 1.9 px
    # each verdict is against the fair nominal for its own postures: "before" the dataset's
    # frames alone, "after" with the 5 added (the URDF's mount is no reference). Not one against
    # the other: more postures lower the fair nominal's noise part, but not its bias, the held
    # parameters' deviation that the placement fitted to the pixels carries to the tool point
    # ((I - P) S (I - P)^T, P the projection weighted by the postures' information; the fit
    # matches the camera's poses, not the flange): with the postures the draws through the
    # eigenvectors' root chose it rose 2.738 -> 2.788 mm (0.1 mm, 0.05 deg; 1.967 -> 2.104 mm
    # with the sized one), with the symmetric root's it falls (2.738 -> 1.486, 1.967 -> 1.903).
    # So: each printed verdict is the one of its own figures in plan.json, and the calibration
    # after beats its reference
    for key, ref_key, pred_key in (("before", "nominal_before", "predicted_before_tool_rms_mm"),
                                   ("after", "nominal", "predicted_tool_rms_mm")):  # fmt: skip
        ref = doc[ref_key]
        assert ref["reference"] == "the fair nominal" and ref["drawn_tool_rms_mm"] is None, ref
        line = next(s for s in p.stdout.splitlines() if s.startswith(f"{key}, without"))
        ratio = doc[pred_key] / ref["fair_nominal_tool_rms_mm"]
        assert f"kinematics {ref['fair_nominal_tool_rms_mm']:.3f} mm" in line, line
        said = float(re.findall(r"([0-9.]+) times it", line)[0])  # plan.json's are rounded
        assert abs(said - ratio) < 0.006, (ratio, line)
        assert line.startswith(f"{key}, without") and (
            ("NOT predicted" in line) == (ratio > ref["clear_margin"])), line  # fmt: skip
    assert doc["predicted_tool_rms_mm"] <= AFTER_OF_NOMINAL * doc["nominal"][
        "fair_nominal_tool_rms_mm"], doc  # fmt: skip
    # "before" forecasts no clear gain where the calibration measured one (its cross-validation
    # and evaluate's held-out check beside it): the line says which is which (it did not: new
    # user's trip, session 25)
    line = next(s for s in p.stdout.splitlines() if s.startswith("before, without"))
    held = outcome.held_out_rms()
    measured = doc["measured_before"]
    assert "NOT predicted" in line and measured is not None, line
    assert measured["held_out_px"] == pytest.approx([held["calibrated"], held["nominal"]])
    assert ("that is a forecast, not a measurement" in line
            and f"held out {held['calibrated']:.3f} px against the fair nominal's "
            f"{held['nominal']:.3f} px" in line), line  # fmt: skip
    # docs/plan.md quotes the lines (the default deviation) and the forecast's draws (both):
    # the draws' percentiles as the page's within the Monte Carlo error of a difference of two
    # runs: sqrt 2 standard errors, 3.5 of them for the 8 comparisons of both runs (2 standard
    # errors failed a clean-clone CI: 0.1568 against the page's 0.164 mm, standard error 0.0034,
    # when the draws went through the eigenvectors' root; through the symmetric root 5
    # calibrations and 3 copies of calibration.json moved by 1e-12 gave the medians within
    # 0.0012 mm, but another machine's round-off can still tip a draw on the selection's edge)
    page = (Path(__file__).resolve().parents[2] / "docs/plan.md").read_text()
    lines = p.stdout.replace(str(runs_dir / name / "calib"), "calib").strip().splitlines()
    assert len(lines) == 6, p.stdout
    # the corner noise the forecast assumed: the calibration's, from its residuals (the default
    # 0.5 px was used where the calibration knew its noise: new user's trip, session 27)
    assert lines[1].startswith("corner noise ") and doc["pixel_sigma"]["source"] == "calibration"
    cal = json.loads((runs_dir / name / "calib/calibration.json").read_text())
    assert doc["pixel_sigma"]["px"] == pytest.approx(cal["bounds"]["pixel_sigma_px"], abs=1e-6)
    if not deviation:  # the same 5 postures in 5 calibrations and 3 copies of calibration.json
        # moved by 1e-12 (docs/plan.md; through the eigenvectors' root 3 of 10 runs flipped them)
        assert all(line in page for line in lines[:5]), p.stdout
    flat = " ".join(page.split())
    if deviation:  # its prose quotes the first line's figures and joint path (the same postures)
        said = re.search(r"error ([0-9.]+ -> [0-9.]+ mm) RMS .*; (joint path [0-9]+ deg)", lines[0])
        assert said and f"prints {said[1]} ({said[2]})" in flat, lines[0]
    fc = doc["forecast_draws"]
    for key in ("before", "after"):
        said = re.findall(rf"{fc[key]['label']}: median ([0-9.]+) mm, 90th percentile "
                          r"([0-9.]+) mm", flat)[1 if deviation else 0]  # fmt: skip
        for v, p_ in zip(map(float, said), ("median", "p90")):
            se = fc[key][f"{p_}_standard_error_mm"]
            assert abs(v - fc[key][f"{p_}_mm"]) < 3.5 * np.sqrt(2) * se, fc
    q = np.radians(doc["joints_deg"])
    limits = load_robot(real.root / real.robot).limits
    assert len(q) == 5 and np.all((q >= limits[:, 0]) & (q <= limits[:, 1]))


@pytest.mark.parametrize("name", [c for c in cases("check") if c.values[0] != ICAL])
def test_check_finds_the_held_out_group_unchanged(name, outcome, runs_dir):
    """`selfcal check CAL HELD` (docs/tool-accuracy.md): group 6 was recorded in the same
    session as groups 1-5 on the same arm, nothing changed in between: the drift check must say
    unchanged (exit 0; it allows 1 % false alarms)."""
    outcome.held_out_rms()  # import and calibrate ran
    argv = ["check", str(runs_dir / name / "calib"), str(runs_dir / name / "held"), "--json"]
    p = subprocess.run([_selfcal_exe(), *argv], capture_output=True, text=True, timeout=1200,
                       check=False)  # fmt: skip
    assert p.returncode in (0, 5), p.stdout + p.stderr
    doc = json.loads(p.stdout)
    assert p.returncode == 0 and doc["verdict"] == "unchanged", doc["line"]


@pytest.mark.parametrize("name", [pytest.param(PHOTONEO, id=PHOTONEO)])
def test_export_of_a_urdf_robot_says_its_tool_tip_is_the_camera(name, outcome, runs_dir, tmp_path):
    """The Nachi URDF has no [camera_mount]: the exported tool tip is the camera, 167.1 mm and
    91.0 deg from the flange as calibrated (`selfcal export --format tf`'s flange -> camera).
    `selfcal export --format urdf` and `ik --calibration` said nothing of it (session 25's
    new-user trip: ik's joints 15 deg from the nominal's at j2, 87 deg at j6)."""
    outcome.held_out_rms()  # import and calibrate ran
    argv = ["export", str(runs_dir / name / "calib"), "--format", "urdf", "--out",
            str(tmp_path / "nachi.urdf")]  # fmt: skip
    p = subprocess.run([_selfcal_exe(), *argv], capture_output=True, text=True, timeout=1200,
                       check=False)  # fmt: skip
    assert p.returncode == 0, p.stdout + p.stderr
    assert "gives no [camera_mount]" in p.stderr, p.stderr
    # and the predicted tool-point accuracy is the camera's, which it called "the flange"
    acc = json.loads((runs_dir / name / "calib" / "calibration.json").read_text())["accuracy"]
    assert acc["tool_point"].startswith("the camera: the robot file gives no [camera_mount]")
    assert "tool point (the camera: " in acc["what"], acc["what"]
    assert re.search(
        r"\(z along its view, 1[67]\d\.\d mm and 9[01]\.\d deg from the flange", p.stderr
    )


def _renamed_with(src: Path, extra: Path, out: Path) -> None:
    """A dataset ``out`` holding the frames of the dataset ``src`` in reversed order under other
    names (frame i of n becomes n - 1 - i: another file, joints.csv row and planned posture),
    then those of ``extra``: the same images and joint readings as the two, re-exported."""
    info = json.loads((src / "dataset.json").read_text())
    more = json.loads((extra / "dataset.json").read_text())
    rows = [r.split(",", 1)[1] for r in (src / "joints.csv").read_text().splitlines()[1:]]
    rows_x = [r.split(",", 1)[1] for r in (extra / "joints.csv").read_text().splitlines()[1:]]
    n = len(rows)
    assert n == len(info["trajectory_joints_deg"]), "a frame without its joints row"
    (out / "frames").mkdir(parents=True)
    order = [(src, i) for i in reversed(range(n))] + [(extra, i) for i in range(len(rows_x))]
    joints, sources = [], []
    for k, (ds, i) in enumerate(order):
        shutil.copy(ds / "frames" / f"{i:04d}_cam0.png", out / "frames" / f"{k:04d}_cam0.png")
        joints.append(f"{k},{(rows if ds == src else rows_x)[i]}")
        sources.append(f"{k},cam0,{ds / 'frames' / f'{i:04d}_cam0.png'}")
    head = (src / "joints.csv").read_text().splitlines()[0]
    (out / "joints.csv").write_text("\n".join([head, *joints]) + "\n")
    (out / "sources.csv").write_text("\n".join(["index,camera,source", *sources]) + "\n")
    info["trajectory_joints_deg"] = (info["trajectory_joints_deg"][::-1]
                                     + more["trajectory_joints_deg"])  # fmt: skip
    (out / "dataset.json").write_text(json.dumps(info))
    shutil.copytree(src / "robot", out / "robot")


@pytest.mark.parametrize("name", [c for c in cases("check") if c.values[0] != ICAL])
def test_check_leaves_out_the_calibrations_own_images(name, outcome, runs_dir):
    """`selfcal check CAL CAL` (the calibration's own images, what a new user tries first) said
    on photoneo "changed by 0.000 mm at the tool point ... p = 0.001; what changed: the
    camera's intrinsics (fx +1.727, k1 -0.008)": their residuals are the fit's, which the check's
    directed tests, weighing each view by its own misfit, read as a camera change
    (selfcal/calibration/drift/own.py). Its own images are now left out and counted; with
    nothing left to test the check is refused (exit 2, the folder named). Found by content, not by name: the same images re-exported in
    reversed order under other names, with the held-out group beside them, leave the held-out
    images tested (unchanged, as test_check_finds_the_held_out_group_unchanged) and the
    calibration's own counted."""
    outcome.held_out_rms()  # import and calibrate ran
    cal, held = runs_dir / name / "calib", runs_dir / name / "held"
    n_cal, n_held = len(outcome.kept["calib"]), len(outcome.kept["held"])
    p = subprocess.run([_selfcal_exe(), "check", str(cal), str(cal), "--json"],
                       capture_output=True, text=True, timeout=1200, check=False)  # fmt: skip
    assert p.returncode == 2, p.stdout + p.stderr
    assert f"all {n_cal} image(s) are the calibration's own frames" in p.stderr, p.stderr

    mixed = runs_dir / name / "renamed-with-held"
    _renamed_with(cal, held, mixed)
    p = subprocess.run([_selfcal_exe(), "check", str(cal), str(mixed), "--json"],
                       capture_output=True, text=True, timeout=1200, check=False)  # fmt: skip
    assert p.returncode == 0, p.stdout + p.stderr
    doc = json.loads(p.stdout)
    assert doc["images"] == n_held and doc["own_images"] == n_cal, doc["line"]
    assert f"{n_cal} more image(s) are the calibration's own" in doc["line"]


def _renoised(src: Path, out: Path, frames: list[int], grey: float, seed: int = 0) -> None:
    """A dataset ``out`` of the frames ``frames`` of the dataset ``src`` (their joint readings)
    with Gaussian noise of ``grey`` grey levels added to each image: new exposures at the
    calibration's postures as far as the images can stand in for them (a proxy: the frames'
    own noise stays in them)."""
    info = json.loads((src / "dataset.json").read_text())
    rows = [r.split(",", 1)[1] for r in (src / "joints.csv").read_text().splitlines()[1:]]
    rng = np.random.default_rng(seed)
    (out / "frames").mkdir(parents=True)
    for k, i in enumerate(frames):
        img = cv2.imread(str(src / "frames" / f"{i:04d}_cam0.png"), cv2.IMREAD_UNCHANGED)
        noisy = np.clip(img + rng.normal(0.0, grey, img.shape), 0, np.iinfo(img.dtype).max)
        cv2.imwrite(str(out / "frames" / f"{k:04d}_cam0.png"), noisy.round().astype(img.dtype))
    head = (src / "joints.csv").read_text().splitlines()[0]
    (out / "joints.csv").write_text("\n".join([head, *(f"{k},{rows[i]}" for k, i in
                                                        enumerate(frames))]) + "\n")  # fmt: skip
    (out / "sources.csv").write_text("index,camera,source\n" + "".join(
        f"{k},cam0,{src / 'frames' / f'{i:04d}_cam0.png'}\n" for k, i in enumerate(frames)))  # fmt: skip
    info["trajectory_joints_deg"] = [info["trajectory_joints_deg"][i] for i in frames]
    (out / "dataset.json").write_text(json.dumps(info))
    shutil.copytree(src / "robot", out / "robot")


@pytest.mark.parametrize("name", [c for c in cases("check") if c.values[0] != ICAL])
def test_a_morning_check_at_the_calibrations_postures(name, outcome, runs_dir):
    """A morning check at the calibration's own postures (one image of each of its five arm
    configurations, re-exposed: the image with 2 grey levels of noise added, as the sets have no
    posture recorded twice): each against the calibration's frame at its posture (its dataset
    beside its file, a per-view misfit counted in it) the images are unchanged (exit 0) and
    counted as paired. Tested as new views (the calibration's file alone, without its dataset:
    the check before selfcal/calibration/drift/paired.py) they carry their posture's misfit and
    the fit's residual there: these five said changed on mecheye (exit 5) and unchanged at p =
    0.021 on photoneo, and 100 of 100 draws of 5 re-noised frames' corners said changed on both
    sets (`uv run python -m selfcal.benchmarks.drift.real_morning CAL`)."""
    outcome.held_out_rms()  # import and calibrate ran
    cal = runs_dir / name / "calib"
    morning = runs_dir / name / "morning"
    if not morning.exists():
        _renoised(cal, morning, [0, 4, 8, 12, 16], grey=2.0)
    p = subprocess.run([_selfcal_exe(), "check", str(cal), str(morning), "--json"],
                       capture_output=True, text=True, timeout=1200, check=False)  # fmt: skip
    assert p.returncode == 0, p.stdout + p.stderr
    doc = json.loads(p.stdout)
    assert doc["paired_images"] == 5 and doc["own_images"] == 0, doc["line"]
    assert "5 at the calibration's postures, each against its frame there" in doc["line"]
    alone = runs_dir / name / "calibration-without-its-dataset.json"
    shutil.copy(cal / "calibration.json", alone)
    p = subprocess.run([_selfcal_exe(), "check", str(alone), str(morning), "--json"],
                       capture_output=True, text=True, timeout=1200, check=False)  # fmt: skip
    # 6: "cannot tell" (the fit's residuals there within the folds' error, drift/fold_error.py)
    assert p.returncode in (0, 5, 6), p.stdout + p.stderr
    assert json.loads(p.stdout)["paired_images"] == 0


@pytest.mark.parametrize("name", [c for c in cases("check_lens") if c.values[0] != ICAL])
def test_check_finds_a_lens_change_in_the_calibration(name, outcome, runs_dir):
    """The held-out group (real images of the unchanged arm) checked against the calibration
    with its lens's k3 (held at 0 by the calibration) moved by LENS_K3 in its file: the
    prediction moves, the images do not, so the check must say changed (exit 5). Such a change
    lies outside the views' pose spans, where the check counted the bounds' corner noise (0.43 /
    0.63 px, the fit's RMS holding the per-view misfit) and said unchanged (docs/real-data.md);
    the pose span's changes (joint offsets, mounts) it finds as before. The move is 0.5: at the
    0.1 this test used, the prediction moves 0.097 / 0.071 px RMS (photoneo / mecheye), whose
    own noncentrality in the camera's test is 2.75 / 2.00 (its power at the check's
    Bonferroni level 0.9 % / 0.5 %); it was found only because the unchanged group already sat
    near an alarm in that test (18.7 / 23.2 on 8 dof) and the move added to it. The camera test
    finds a k3 move with 95 % power from 0.37 / 0.44 (`uv run python -m
    selfcal.benchmarks.drift.real_lens CAL HELD`)."""
    outcome.held_out_rms()  # import and calibrate ran
    doc = json.loads((runs_dir / name / "calib" / "calibration.json").read_text())
    doc["cameras"][0]["parameters"]["k3"] += LENS_K3[name]
    moved = runs_dir / name / "calibration-k3-moved.json"
    moved.write_text(json.dumps(doc))
    argv = ["check", str(moved), str(runs_dir / name / "held"), "--json"]
    p = subprocess.run([_selfcal_exe(), *argv], capture_output=True, text=True, timeout=1200,
                       check=False)  # fmt: skip
    assert p.returncode in (0, 5), p.stdout + p.stderr
    res = json.loads(p.stdout)
    assert p.returncode == 5 and res["verdict"] == "changed", res["line"]
