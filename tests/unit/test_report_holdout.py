"""`selfcal report`'s leave-poses-out check on real data calibrates a subset afresh (session 25's
new-user trip, the repository's photoneo set): that calibration's warning was printed bare ("the
robot's fit leaves 1.046 px RMS ...") beside calibration.json's own (0.600 px), and its NO GAIN
(1.197 / 1.197 px: it chose the nominal) read as the verdict on calibration.json, which chose the
joint offsets and predicts group 6 at 0.812 against 1.731 px. Both now say whose they are."""

from __future__ import annotations

import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from selfcal.calibration.board.dataset import ReadbackWarning
from selfcal.calibration.board.evaluate import Evaluation
from selfcal.calibration.field import holdout
from selfcal.pipeline.report_fit import _held_out, fit_markdown
from selfcal.pipeline.report_text import report_summary

NOMINAL = "nominal (placement + camera)"
OFFSETS = "+ joint offsets"


def _evaluation() -> Evaluation:
    rows = [{"image": f"{k:04d}_cam0.png", "index": k, "camera": "cam0", "features": 88,
             "nominal_px": 1.197, "calibrated_px": 1.197} for k in range(4)]  # fmt: skip
    return Evaluation({"nominal": 1.197, "calibrated": 1.197}, tuple(rows), (), "held", "fit")


@pytest.fixture
def subset_calibration(monkeypatch, tmp_path):
    """leave_poses_out on a 20-frame board dataset whose subset's calibration warns and chooses
    the nominal (the calibration and evaluation stubbed: what is tested is what is said)."""
    ds = SimpleNamespace(root=tmp_path / "cal", indices=np.arange(20),
                         joints_deg=np.arange(120.0).reshape(20, 6),
                         info=SimpleNamespace(board={"type": "chessboard"}))  # fmt: skip
    monkeypatch.setattr(holdout.Dataset, "open", staticmethod(lambda root: ds))
    monkeypatch.setattr(holdout, "subset_dataset", lambda root, idx, out: SimpleNamespace(root=out))

    def calibrate(root, allow_missing_frames):
        warnings.warn("the robot's fit leaves 1.046 px RMS", ReadbackWarning, stacklevel=1)
        return SimpleNamespace(selection={"chosen": NOMINAL})

    monkeypatch.setattr(holdout, "calibrate_board_dataset", calibrate)
    monkeypatch.setattr(holdout, "evaluate_board", lambda cal, name, root: _evaluation())
    return ds


def test_the_subset_calibrations_warning_names_that_calibration(subset_calibration):
    with pytest.warns(ReadbackWarning) as got:
        h = holdout.leave_poses_out(subset_calibration.root, every=5, method="board")
    (w,) = got.list
    assert str(w.message).startswith(
        "the held-out check's calibration of 16 of 20 frames (every 5th held out; not "
        f"{Path(subset_calibration.root) / 'calibration.json'}): the robot's fit leaves 1.046"
    )
    assert h.chosen == NOMINAL and len(h.held_out) == 4


def test_report_says_the_check_judged_another_choice(subset_calibration):
    with pytest.warns(ReadbackWarning):
        h = _held_out(subset_calibration.root, "board", 5, OFFSETS)
    assert h["chosen"] == NOMINAL
    assert h["selection_note"].startswith(
        f"that calibration chose {NOMINAL} where calibration.json chose {OFFSETS}: these "
        "held-out figures judge its choice, not calibration.json's"
    )
    report = {"kind": "fit", "fit": {"method": "board", "frames": 20, "frames_used": 20,
              "reprojection_rms_px": 0.6}, "held_out": h,
              "identifiability": {"method": "board", "held": {}}, "parameters": [],
              "intrinsics": {}, "warnings": []}  # fmt: skip
    line = report_summary(report, Path("cal"))
    assert f"over 4 images (leave-poses-out; that calibration chose {NOMINAL} where" in line
    assert f"That calibration chose {NOMINAL} where calibration.json" in fit_markdown(report, [])
    # the same choice: nothing to say
    with pytest.warns(ReadbackWarning):
        same = _held_out(subset_calibration.root, "board", 5, NOMINAL)
    assert "selection_note" not in same


def test_an_evaluation_of_another_calibration_is_not_the_reports(subset_calibration):
    """own-data.md says an evaluation.json beside the calibration that evaluates another one is
    not used, and export did not use it, but report did: `selfcal evaluate cal-js held --out
    cal3/evaluation.json` made `selfcal report cal3` say NO GAIN (1.848 / 1.848 px, cal-js's
    figures) of a calibration whose own check is 0.812 against 1.731 px."""
    from selfcal.calibration.board.evaluate import write_evaluation
    from selfcal.errors import SelfCalWarning

    root = Path(subset_calibration.root)
    root.mkdir()
    write_evaluation(root / "evaluation.json", _evaluation())  # of "fit", elsewhere
    with (
        pytest.warns(ReadbackWarning),  # the leave-poses-out check's own calibration
        pytest.warns(SelfCalWarning, match=r"evaluation\.json evaluates fit, not .*: its held-"),
    ):
        h = _held_out(root, "board", 5, OFFSETS)
    assert h["source"] == "leave-poses-out"
    ev = _evaluation()
    write_evaluation(root / "evaluation.json", Evaluation(ev.rms, ev.images, (), "held", str(root)))
    assert _held_out(root, "board", 5, OFFSETS)["source"] == "selfcal evaluate"


def test_an_evaluation_named_relative_to_another_folder_is_still_the_reports(tmp_path, monkeypatch):
    """`selfcal evaluate cal held --out cal/evaluation.json` records "cal" as typed; a report or
    an export of that folder from another working directory is still of that calibration."""
    from selfcal.calibration.board.evaluate import evaluates

    root = tmp_path / "lab" / "cal"
    root.mkdir(parents=True)
    ev = _evaluation()
    of = lambda name: Evaluation(ev.rms, ev.images, (), "held", name)  # noqa: E731
    monkeypatch.chdir(tmp_path)  # not lab/, where evaluate ran
    assert evaluates(of("cal"), root) and evaluates(of("./cal/calibration.json"), root)
    assert evaluates(of("../lab/cal"), root) and evaluates(of(str(root)), root)
    assert not evaluates(of("cal-js"), root) and not evaluates(of("cal3"), root)
    assert not evaluates(of(str(tmp_path / "cal")), root)  # absolute: exactly


@pytest.mark.parametrize("typed", [".", "./", "./calibration.json"])
def test_an_evaluation_of_dot_is_the_reports_from_any_folder(tmp_path, monkeypatch, typed):
    """`selfcal evaluate . held --out evaluation.json` in the calibration's folder records "."
    as typed, which names no folder from another working directory: report and export warned
    "evaluates ., not ..." and ran their own check (review of session 25). The evaluation
    records its calibration.json's absolute path too, which names it from anywhere; another
    calibration's evaluation (".", there) does not name this one."""
    from selfcal.calibration.board.evaluate import evaluates, read_evaluation, write_evaluation

    root, other = tmp_path / "lab" / "cal", tmp_path / "lab" / "cal2"
    for d in (root, other):
        d.mkdir(parents=True)
        (d / "calibration.json").write_text("{}")
    errs = [{"nominal": np.ones((3, 2)), "calibrated": np.zeros((3, 2))}]
    for d in (root, other):
        monkeypatch.chdir(d)  # where evaluate ran
        made = Evaluation.of([{"image": "0000_cam0.png", "camera": "cam0", "features": 3}], errs,
                             (), "held", typed)  # fmt: skip
        write_evaluation(d / "evaluation.json", made)
    monkeypatch.chdir(tmp_path)  # report and export run here
    ev = read_evaluation(root / "evaluation.json")
    assert ev.calibration == typed and ev.calibration_file == str(root / "calibration.json")
    assert evaluates(ev, root) and evaluates(ev, root / "calibration.json")
    assert evaluates(ev, "lab/cal") and not evaluates(ev, other)
    assert not evaluates(read_evaluation(other / "evaluation.json"), root)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not "evaluates ., not ...": its check is used
        assert _held_out(root, "board", 5)["source"] == "selfcal evaluate"


def test_an_evaluation_of_a_calibration_redone_in_place_is_not_used(tmp_path, monkeypatch):
    """`selfcal calibrate DIR` again after `selfcal evaluate DIR held --out DIR/evaluation.json`
    leaves the same path with other contents: report, export and plan --add used the old
    held-out figures without a word (review of session 26). The evaluation records the file's
    SHA-256; one that no longer matches is another calibration's, said and not used; a file
    written before the digest (none recorded) is judged by its paths as before."""
    from selfcal.calibration.board.evaluate import (
        evaluates,
        evaluation_of,
        read_evaluation,
        write_evaluation,
    )
    from selfcal.errors import SelfCalWarning

    root = tmp_path / "cal"
    root.mkdir()
    (root / "calibration.json").write_text('{"first": 1}')
    errs = [{"nominal": np.ones((3, 2)), "calibrated": np.zeros((3, 2))}]
    monkeypatch.chdir(tmp_path)
    made = Evaluation.of([{"image": "0000_cam0.png", "camera": "cam0", "features": 3}], errs,
                         (), "held", "cal")  # fmt: skip
    write_evaluation(root / "evaluation.json", made)
    ev = read_evaluation(root / "evaluation.json")
    assert len(ev.calibration_sha256) == 64 and evaluates(ev, root)
    assert evaluation_of(root)[1] == ev
    (root / "calibration.json").write_text('{"second": 2}')  # calibrated again, in place
    assert not evaluates(ev, root)
    with pytest.warns(SelfCalWarning, match=r"evaluates an earlier .*changed since.*evaluate"):
        assert evaluation_of(root)[1] is None
    older = Evaluation(ev.rms, ev.images, (), "held", "cal", calibration_file=ev.calibration_file)
    assert evaluates(older, root)  # no digest recorded: the paths decide
