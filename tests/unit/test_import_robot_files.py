"""A stranger's robot files through ``selfcal import`` (the acceptance run of session 5).

A hand-written 7-axis URDF as labs have them: a root ``world`` link above the arm's base, a
fixed flange, a hand and two gripper fingers (one a mimic joint), so the default tool link is
ambiguous; a robot TOML whose ``[urdf] file`` lies in a sub-folder; image files numbered without
padding. Each case failed before it was fixed here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.importing.dataset import CameraImages, ImportError_, import_dataset, name_order
from selfcal.robot.definition import RobotDefinitionError, load_robot
from selfcal.robot.urdf import UrdfError, urdf_chain

_ARM = [  # Panda-like: franka_description's joint origins (xyz m, rpy rad) and limits (rad)
    ("j1", (0, 0, 0.333), (0, 0, 0), -2.9, 2.9),
    ("j2", (0, 0, 0), (-np.pi / 2, 0, 0), -1.76, 1.76),
    ("j3", (0, -0.316, 0), (np.pi / 2, 0, 0), -2.9, 2.9),
    ("j4", (0.0825, 0, 0), (np.pi / 2, 0, 0), -3.07, -0.07),  # 0 is outside the range
    ("j5", (-0.0825, 0.384, 0), (-np.pi / 2, 0, 0), -2.9, 2.9),
    ("j6", (0, 0, 0), (np.pi / 2, 0, 0), -0.02, 3.75),
    ("j7", (0.088, 0, 0), (np.pi / 2, 0, 0), -2.9, 2.9),
]


def _urdf() -> str:
    links = ["world", "link0"] + [f"link{k}" for k in range(1, 9)] + ["hand", "lf", "rf"]
    out = ['<?xml version="1.0"?>', '<robot name="arm7">'] + [f'<link name="{n}"/>' for n in links]

    def joint(name, kind, parent, child, xyz, rpy, extra=""):
        out.append(
            f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{" ".join(map(str, xyz))}" rpy="{" ".join(map(str, rpy))}"/>{extra}'
            "</joint>"
        )

    joint("world_joint", "fixed", "world", "link0", (0.1, -0.2, 0.75), (0, 0, 0.3))
    for k, (name, xyz, rpy, lo, hi) in enumerate(_ARM):
        lim = f'<axis xyz="0 0 1"/><limit lower="{lo}" upper="{hi}" effort="1" velocity="1"/>'
        joint(name, "revolute", f"link{k}", f"link{k + 1}", xyz, rpy, lim)
    joint("flange", "fixed", "link7", "link8", (0, 0, 0.107), (0, 0, 0))
    joint("hand_joint", "fixed", "link8", "hand", (0, 0, 0), (0, 0, -np.pi / 4))
    finger = '<axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="1" velocity="1"/>'
    joint("f1", "prismatic", "hand", "lf", (0, 0, 0.0584), (0, 0, 0), finger)
    joint("f2", "prismatic", "hand", "rf", (0, 0, 0.0584), (0, 0, 0),
          finger + '<mimic joint="f1"/>')  # fmt: skip
    return "\n".join(out + ["</robot>", ""])


@pytest.fixture
def arm(tmp_path) -> Path:
    p = tmp_path / "arm7.urdf"
    p.write_text(_urdf())
    return p


def test_a_tool_link_alone_takes_the_root_as_base(arm):
    """``--tool-link`` without ``--base-link``: the root is the base and the fingers' tie does not
    matter (before: the tie was an error even with the tool link named)."""
    ch = urdf_chain(arm, tool_link="link8")
    assert ch.base_link == "world" and ch.joint_names == tuple(j[0] for j in _ARM)
    ch = urdf_chain(arm, base_link="link0", tool_link="hand")
    assert ch.base_link == "link0" and len(ch.joint_names) == 7


def test_the_ambiguous_tool_link_names_the_command_line_options(arm):
    with pytest.raises(UrdfError, match="leaf links lf, rf") as e:
        urdf_chain(arm, base_link="link0")
    assert "--tool-link" in e.value.fix  # before: only a robot TOML's [urdf] table
    with pytest.raises(UrdfError, match="no link named 'flange'") as e:
        urdf_chain(arm, tool_link="flange")
    assert "--tool-link" in e.value.fix


def test_a_urdf_robot_toml_without_home_starts_inside_the_ranges(arm, tmp_path):
    """A robot TOML naming the URDF's links (what ``import --tool-link`` writes) gets the bare
    URDF's home: 0, or mid-range where 0 is outside (before: joint 4 = 0 was refused)."""
    toml = tmp_path / "arm.toml"
    toml.write_text('name = "arm7"\n[urdf]\nfile = "arm7.urdf"\ntool_link = "hand"\n')
    robot = load_robot(toml)
    assert np.all(robot.home >= robot.limits[:, 0]) and np.all(robot.home <= robot.limits[:, 1])
    assert robot.home[3] == pytest.approx(np.mean(robot.limits[3]))


def test_image_files_numbered_without_padding_sort_by_number(tmp_path):
    """``img_2`` before ``img_10``: rows match the images in the camera's order (before:
    ``img_10`` came second and every joints row met another posture's image)."""
    for k in (1, 2, 10, 11, 3):
        (tmp_path / f"view-{k}.png").write_bytes(b"")
    cam = CameraImages.parse(f"cam0={tmp_path}/*.png")
    assert [p.name for p in cam.files] == [f"view-{k}.png" for k in (1, 2, 3, 10, 11)]
    assert sorted(["b1", "a10", "a2", "a02x"], key=name_order) == ["a2", "a02x", "a10", "b1"]


def _import(robot: Path, out: Path, tmp_path: Path, **kw):
    (tmp_path / "board.toml").write_text('type = "chessboard"\ninner_corners = [11, 8]\n'
                                         "square_mm = 20.0\n")  # fmt: skip
    (tmp_path / "img.png").write_bytes(b"")
    (tmp_path / "joints.csv").write_text("j1,j2,j3,j4,j5,j6,j7\n" + "0,0,0,-1,0,1,0\n")
    cams = [CameraImages.parse(f"cam0={tmp_path}/img.png")]
    return import_dataset(str(robot), cams, tmp_path / "joints.csv", "rad",
                          tmp_path / "board.toml", out, **kw)  # fmt: skip


def test_a_failed_import_names_the_users_file_and_leaves_no_folder(arm, tmp_path):
    out = tmp_path / "ds"
    with pytest.raises(UrdfError) as e:
        _import(arm, out, tmp_path)
    assert str(arm) in str(e.value) and "ds/robot" not in str(e.value)  # not the dataset's copy
    assert not out.exists()  # before: out/robot/ stayed behind
    kept = tmp_path / "mine"
    kept.mkdir()
    with pytest.raises(UrdfError):
        _import(arm, kept, tmp_path)
    assert kept.is_dir()  # a folder the user made is left alone


def test_a_robot_toml_brings_its_urdf_into_the_dataset(arm, tmp_path):
    """A robot TOML whose ``[urdf] file`` is ``desc/arm7.urdf``: the dataset holds both files and
    its robot loads from them (before: only the TOML was copied and the URDF was not found)."""
    (tmp_path / "cfg" / "desc").mkdir(parents=True)
    arm.rename(tmp_path / "cfg" / "desc" / "arm7.urdf")
    toml = tmp_path / "cfg" / "robot.toml"
    toml.write_text('name = "arm7"\n[urdf]\nfile = "desc/arm7.urdf"\nbase_link = "link0"\n'
                    'tool_link = "hand"\n')  # fmt: skip
    out = tmp_path / "ds"
    with pytest.raises(ImportError_, match="not a readable image"):  # past the robot's copy
        _import(toml, out, tmp_path)
    out.mkdir()
    with pytest.raises(ImportError_, match="not a readable image"):
        _import(toml, out, tmp_path)
    assert sorted(p.name for p in (out / "robot").iterdir()) == ["arm7.urdf", "robot.toml"]
    assert load_robot(out / "robot" / "robot.toml").n == 7


_MDH = """name = "arm7-mdh"
convention = "mdh"
home_deg = [0.0, -17.0, 0.0, -126.0, 0.0, 112.0, 45.0]
""" + "".join(
    f'[[joint]]\nname = "{n}"\nalpha_deg = {np.degrees(r[0]):.1f}\na_mm = {1e3 * x[0]:.1f}\n'
    f"d_mm = {1e3 * (x[2] - x[1]):.1f}\nrange_deg = [{np.degrees(lo):.1f}, {np.degrees(hi):.1f}]\n"
    for n, x, r, lo, hi in _ARM
)


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (lambda t: t + "[flange]\nd_mm = 107.0\n", "'flange'"),  # an invented table
        (lambda t: t.replace("d_mm = 316.0", "d_mm = 316.0\ntheta_deg = 0.0", 1), "'theta_deg'"),
        (lambda t: "nmae = 'x'\n" + t, "'nmae'"),
    ],
)
def test_a_robot_toml_with_an_unknown_key_is_refused(tmp_path, edit, key):
    """A key the robot file may not hold (before: silently ignored, e.g. a [flange] table left
    the 107 mm flange out of the chain without a word)."""
    good = tmp_path / "arm.toml"
    good.write_text(_MDH)
    assert load_robot(good).n == 7
    bad = tmp_path / "bad.toml"
    bad.write_text(edit(_MDH))
    with pytest.raises(RobotDefinitionError, match=f"unknown key.*{key}") as e:
        load_robot(bad)
    assert str(bad) in str(e.value) and e.value.fix and "name" in e.value.fix


def test_an_image_column_naming_a_missing_image_names_its_row_and_the_fix(tmp_path):
    """One image of a recording missing (never saved) while the joints file's image column
    names it: the error said only 'lacks, e.g. 0007.png' and asked to 'name files of the
    --images folders', not which row or that the row or the image is what to mend."""
    from selfcal.importing.dataset import _match

    for k in (0, 1, 2, 4):
        (tmp_path / f"{k:04d}.png").write_bytes(b"")
    column = tuple(f"{k:04d}.png" for k in range(5))
    cams = [CameraImages.parse(f"cam0={tmp_path}/*.png")]
    with pytest.raises(
        ImportError_, match=r"lacks, e\.g\. '0003\.png' \(data row 4; rows 4\)"
    ) as e:
        _match(cams, column, 5, tmp_path / "joints.csv")
    assert "remove their rows from the joints file" in str(e.value.fix)
    assert [p.name for p in _match(cams, column[:3] + column[4:], 4, tmp_path / "j.csv")["cam0"]] \
        == ["0000.png", "0001.png", "0002.png", "0004.png"]  # fmt: skip


def test_a_link_saved_as_text_names_the_file_it_points_to(tmp_path):
    """A real set's ``images_calib/01.png`` was a 49-byte text naming
    ``../../examples/data/test_set_charuco/images/1.png`` (a symbolic link copied as text):
    import said "not a readable image -- remove it or convert it to PNG"."""
    from selfcal.importing.dataset import detect_images

    (tmp_path / "real").mkdir()
    real = tmp_path / "real" / "1.png"
    real.write_bytes(b"\x89PNG")
    (tmp_path / "links").mkdir()
    link = tmp_path / "links" / "01.png"
    link.write_text("../real/1.png")
    cam = CameraImages.parse(f"cam0={tmp_path}/links/*.png")
    with pytest.raises(ImportError_) as e:
        detect_images(cam, [link], None)  # type: ignore[arg-type]  # refused before detecting
    assert e.value.message == (f"{link}: not an image but a 13-byte text naming ../real/1.png: "
                               "a symbolic link saved as a text file (by git without symlink "
                               "support, an archive or a copy)")  # fmt: skip
    assert str(real.resolve()) in e.value.fix and "core.symlinks" in e.value.fix
    other = tmp_path / "links" / "02.png"  # text naming no file: as before
    other.write_text("not a path")
    with pytest.raises(ImportError_, match=r"not a readable image \(fix: remove it or convert it"):
        detect_images(cam, [other], None)  # type: ignore[arg-type]
