"""``selfcal check`` with images against a board calibration: exit 0 unchanged / 5 changed and
what changed (#29). A simulated calibration (analytic mono-charuco, 0.2 px) and six new images of
the same robot at new postures."""

from __future__ import annotations

import csv
import dataclasses
import json
import re
import shutil

import numpy as np
import pytest

import selfcal
from selfcal.calibration.drift.images import calibration_error_model, estimate_covariance
from selfcal.calibration.drift.verdict import UNSEEN_NOTE
from selfcal.cli.check import EXIT_CHANGED
from selfcal.cli.main import main
from selfcal.config.scenario import load_scenario, scenarios_dir
from selfcal.errors import InputError
from selfcal.io.board_calibration import read_board_calibration, write_board_calibration
from selfcal.pipeline.run import run_acquire, run_all


def _offset_joint(src, dst, column: int, deg: float) -> None:
    """Copy the dataset ``src`` to ``dst`` with ``deg`` added to joint ``column``'s readings."""
    shutil.copytree(src, dst)
    rows = list(csv.reader((dst / "joints.csv").read_text().splitlines()))
    for r in rows[1:]:
        r[column] = f"{float(r[column]) + deg:.6f}"
    with (dst / "joints.csv").open("w", newline="") as f:
        csv.writer(f).writerows(rows)


@pytest.mark.slow
def test_check_with_images_says_unchanged_or_changed(tmp_path, capsys):
    scenario = scenarios_dir() / "mono-charuco.toml"
    noise = {"render": False, "pixel_sigma": 0.2}
    cal = tmp_path / "cal"
    run_all(load_scenario(scenario, {"noise": noise}), cal, quiet=True, figures=False)
    new = tmp_path / "new"  # the same robot (perturbation seed), new postures and noise
    run_acquire(load_scenario(scenario, {"noise": noise | {"seed": 78},
                                         "trajectory": {"poses": 6, "seed": 77}}),
                new, quiet=True)  # fmt: skip
    capsys.readouterr()
    assert main(["check", str(cal), str(new)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("unchanged: 6 new image(s)")
    # the check's power for these images against a 0.2 mm move of the camera's mount, from the
    # calibration's covariance (selfcal/calibration/drift/power.py)
    assert out.splitlines()[1].startswith("power: 6 image(s) like these find a 0.2 mm move")

    # the calibration's own images, in its folder or copied elsewhere: nothing to test, an
    # input error naming the folder (their residuals are the fit's,
    # selfcal/calibration/drift/own.py); a cell's morning check of the wrong folder must not pass
    assert main(["check", str(cal), str(cal)]) == 2
    err = capsys.readouterr().err
    assert "are the calibration's own frames" in err
    # the fix named `selfcal record` (the Rerun recording of a run), which makes no images
    # (session 25's new-user trip): new images come from `selfcal import` (or acquire)
    assert "`selfcal import ... --out NEW`" in err and "selfcal record" not in err, err
    copy = tmp_path / "copy"
    shutil.copytree(cal, copy, ignore=shutil.ignore_patterns("calibration.json"))
    with pytest.raises(
        InputError, match=r"copy: all \d+ image\(s\) are the calibration's own"
    ) as err:
        selfcal.check_images(cal, copy)
    n_own = int(re.findall(r"all (\d+) image", str(err.value))[0])
    _offset_joint(cal, tmp_path / "own-joint", 4, 0.3)  # its frames, joint 4 read 0.3 deg off
    res = selfcal.check_images(cal, tmp_path / "own-joint")
    assert res.own == 0 and res.views == n_own and res.changed and "joint 4" in res.line()
    block = read_board_calibration(cal).accuracy
    assert block is not None and np.shape(block["camera_cross_si"]) == (
        len(block["estimated"]), 8)  # fmt: skip
    # the estimate's part from the frames' noise alone (the pairing's cross term): within the
    # whole covariance (which adds the held deviation's share), the same order
    em = calibration_error_model(read_board_calibration(cal), "calibration.json")
    whole, part = (
        estimate_covariance(read_board_calibration(cal), em),
        np.array(block["noise_covariance_si"]),
    )
    assert part.shape == whole.shape and np.linalg.eigvalsh(part).min() > -1e-9 * np.abs(part).max()
    assert np.linalg.eigvalsh(whole - part).min() > -1e-6 * np.abs(whole).max()
    assert np.any(part != 0)

    old = tmp_path / "old"  # a file written before the camera covariance: its sigmas alone
    shutil.copytree(cal, old)
    doc = json.loads((old / "calibration.json").read_text())
    del doc["accuracy"]["camera_covariance_si"], doc["accuracy"]["camera_cross_si"]
    (old / "calibration.json").write_text(json.dumps(doc))
    res = selfcal.check_images(old, new)
    assert (
        not res.changed
        and res.expected_rms_px > 1.2 * selfcal.check_images(cal, new).expected_rms_px
    )

    bad = tmp_path / "bad"  # a hand-edited per-view misfit: the error names the file
    shutil.copytree(cal, bad)
    doc = json.loads((bad / "calibration.json").read_text())
    doc["accuracy"]["view_jitter"] = {"covariance_si": "not a matrix"}
    (bad / "calibration.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=re.escape(f"{bad / 'calibration.json'}: accuracy.")):
        selfcal.check_images(bad, new)

    _offset_joint(new, tmp_path / "joint", 4, 0.3)  # joint 4 read 0.3 deg off
    assert main(["check", str(cal), str(tmp_path / "joint"), "--json"]) == EXIT_CHANGED
    doc = json.loads(capsys.readouterr().out)
    assert doc["verdict"] == "changed" and doc["p_value"] < 1e-6
    power = doc["mount_shift_power"]
    assert power["images"] == 6 and power["size_mm"] == 0.2 and 0.0 <= power["power"] <= 1.0
    assert "joint 4" in [c["change"] for c in doc["cause"]["explained_by"]]
    # every new posture is a configuration the calibration did not see: the verdict says that
    # its false-alarm rate there is measured in simulation only
    assert doc["unseen_configuration_images"] == 6 and UNSEEN_NOTE in doc["line"]

    moved = tmp_path / "moved"  # the camera 2 mm along its x axis on the flange since then
    shutil.copytree(cal, moved)
    c = read_board_calibration(moved)
    shift = np.eye(4)
    shift[0, 3] = 2e-3
    write_board_calibration(moved / "calibration.json",
                            dataclasses.replace(c, model=c.model.with_tool(shift)))  # fmt: skip
    res = selfcal.check_images(moved, new)
    assert res.changed and res.p_value < 1e-6
    assert res.attribution is not None and "hand-eye" in res.attribution.explaining
    assert res.best == "hand-eye" and 1.5 < res.change_mm < 2.5
    assert main(["check", str(moved), str(new)]) == EXIT_CHANGED
    assert capsys.readouterr().out.startswith("changed by")

    # one corner of one new image detected 5 px off: dropped by the calibration's outlier rule
    # after its view's own pose fit (not read as a noisy image or a change) and named
    off = tmp_path / "outlier"
    shutil.copytree(new, off)
    rows = list(csv.reader((off / "detections.csv").read_text().splitlines()))
    col = rows[0].index("u_px")
    rows[1][col] = f"{float(rows[1][col]) + 5.0:.6f}"
    with (off / "detections.csv").open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    res = selfcal.check_images(cal, off)
    assert not res.changed and len(res.outliers) == 1, res.line()
    name, u, _, err = res.outliers[0]
    assert u == pytest.approx(float(rows[1][col])) and 4.0 < err < 6.0
    assert main(["check", str(cal), str(off)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("unchanged: 6 new image(s)") and f"{name} at ({u:.1f}," in out
    # a real change beside it is still found
    _offset_joint(off, tmp_path / "outlier-joint", 4, 0.3)
    res = selfcal.check_images(cal, tmp_path / "outlier-joint")
    assert res.changed and len(res.outliers) == 1 and "joint 4" in res.line()

    assert main(["check", str(cal), str(tmp_path / "nothing")]) == 2  # no dataset: named
    assert str(tmp_path / "nothing") in capsys.readouterr().err
