"""Flange pose files: every rotation convention reads to the same poses; bad input is named."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.io.poses.files import PoseFileError, read_poses
from selfcal.transforms import make_pose

RNG = np.random.default_rng(3)
ROT = Rotation.random(5, random_state=4)
XYZ_MM = RNG.uniform(-800, 800, (5, 3))
TRUE = make_pose(ROT.as_matrix(), XYZ_MM / 1000.0)


def _csv(path, header, rows):
    path.write_text(
        ",".join(header) + "\n" + "".join(",".join(f"{v:.12g}" for v in r) + "\n" for r in rows)
    )
    return path


def _columns(convention):
    """The header and orientation values of ``convention`` for the poses TRUE."""
    q = ROT.as_quat()  # x, y, z, w
    zyx = ROT.as_euler("ZYX", degrees=True)  # A, B, C
    return {
        "quaternion-xyzw": (["qx", "qy", "qz", "qw"], q),
        "abb-quaternion": (["q1", "q2", "q3", "q4"], q[:, [3, 0, 1, 2]]),
        "kuka-abc": (["A", "B", "C"], zyx),
        "fanuc-wpr": (["W", "P", "R"], ROT.as_euler("xyz", degrees=True)),
        "ur-rotvec": (["rx", "ry", "rz"], ROT.as_rotvec()),
    }[convention]


@pytest.mark.parametrize(
    "convention", ["quaternion-xyzw", "abb-quaternion", "kuka-abc", "fanuc-wpr", "ur-rotvec"]
)
def test_each_convention_reads_the_same_poses(tmp_path, convention):
    cols, vals = _columns(convention)
    f = _csv(tmp_path / "p.csv", ["x_mm", "y_mm", "z_mm", *cols], np.hstack([XYZ_MM, vals]))
    rows = read_poses(f, convention if convention == "ur-rotvec" else None)
    assert rows.convention == convention
    np.testing.assert_allclose(rows.T_base_flange, TRUE, atol=1e-12)


def test_kuka_abc_is_fanuc_wpr_reversed(tmp_path):
    abc = ROT.as_euler("ZYX", degrees=True)
    f = _csv(tmp_path / "p.csv", ["x", "y", "z", "rx", "ry", "rz"],
             np.hstack([XYZ_MM / 1000.0, abc[:, ::-1]]))  # fmt: skip
    rows = read_poses(f, "fanuc-wpr", "m")
    np.testing.assert_allclose(rows.T_base_flange, TRUE, atol=1e-12)


def test_ambiguous_rx_ry_rz_needs_the_convention(tmp_path):
    f = _csv(tmp_path / "p.csv", ["x_mm", "y_mm", "z_mm", "rx", "ry", "rz"], np.zeros((2, 6)))
    with pytest.raises(PoseFileError, match="--rotation kuka-abc"):
        read_poses(f)


def test_unitless_positions_need_pose_units(tmp_path):
    cols, vals = _columns("quaternion-xyzw")
    f = _csv(tmp_path / "p.csv", ["x", "y", "z", *cols], np.hstack([XYZ_MM, vals]))
    with pytest.raises(PoseFileError, match="--pose-units"):
        read_poses(f)
    np.testing.assert_allclose(read_poses(f, units="mm").T_base_flange, TRUE, atol=1e-12)


def test_bad_value_named_by_line_and_column(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("x_mm,y_mm,z_mm,qx,qy,qz,qw\n1,2,3,0,0,0,1\n1,2,oops,0,0,0,1\n")
    with pytest.raises(PoseFileError, match=r"line 3, column 'z_mm': 'oops'"):
        read_poses(f)


def test_rotation_too_large_to_compute_is_named(tmp_path):
    """A rotation vector whose norm overflows gave a NaN pose silently (found by the fuzz test)."""
    f = tmp_path / "p.csv"
    f.write_text("x,y,z,rx,ry,rz\n0.1,0.2,0.3,0,0,0\n0.1,0.2,0.3,1.34e154,1.34e154,0\n")
    with pytest.raises(PoseFileError, match=r"line 3: the orientation \(rx, ry, rz\)"):
        read_poses(f, "ur-rotvec", "m")


def test_quaternion_in_the_wrong_order_is_named(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("x_mm,y_mm,z_mm,q1,q2,q3,q4\n1,2,3,1,0,0,0\n1,2,3,0.5,0.5,0.5,0.9\n")
    with pytest.raises(PoseFileError, match="line 3: the quaternion"):
        read_poses(f)


def test_industrial_calibration_yaml(tmp_path):
    (tmp_path / "poses").mkdir()
    q = ROT.as_quat()
    lines = ["data:"]
    for k in range(5):
        x, y, z = XYZ_MM[k] / 1000.0
        (tmp_path / "poses" / f"{k}.yaml").write_text(
            "".join(
                f"{key}: {v:.17g}\n"
                for key, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), (x, y, z, *q[k]))
            )
        )
        lines += [f"  - image: images/{k}.png", f"    pose: poses/{k}.yaml"]
    (tmp_path / "cal_data.yaml").write_text("\n".join(lines) + "\n")
    rows = read_poses(tmp_path / "cal_data.yaml")
    np.testing.assert_allclose(rows.T_base_flange, TRUE, atol=1e-12)
    assert rows.images is not None and rows.images[3].endswith("images/3.png")
    np.testing.assert_allclose(read_poses(tmp_path / "poses").T_base_flange, TRUE, atol=1e-12)
    (tmp_path / "poses" / "2.yaml").write_text("x: 1\ny: 2\n")
    with pytest.raises(PoseFileError, match=r"2.yaml: no key 'z'"):
        read_poses(tmp_path / "cal_data.yaml")


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "--poses needs --setup"),
        (["--setup", "eye-to-hand", "--robot", "ur5e"], "flange poses need no robot model"),
        (["--setup", "eye-to-hand", "--joint-units", "deg"], "--joint-units applies to --joints"),
    ],
)
def test_cli_pose_import_refuses_mixed_options(tmp_path, capsys, extra, message):
    from selfcal.cli.main import main

    f = _csv(
        tmp_path / "p.csv",
        ["x_mm", "y_mm", "z_mm", "qx", "qy", "qz", "qw"],
        [[0, 0, 0, 0, 0, 0, 1]],
    )
    argv = ["import", "--poses", str(f), "--target", "t.toml", "--out", str(tmp_path / "o")]
    assert main(argv + extra) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_cli_joints_import_still_needs_a_robot(tmp_path, capsys):
    from selfcal.cli.main import main

    argv = ["import", "--joints", "j.csv", "--joint-units", "deg", "--images", "x/*.png",
            "--target", "t.toml", "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(argv) == 2
    assert "needs --robot" in capsys.readouterr().err
