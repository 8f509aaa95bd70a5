"""Robots from a URDF (selfcal.robot.urdf through load_robot).

Ground truth: the same arm written independently in modified DH (models/kuka_kr6_r900/kr6-r900.toml) and
in URDF (tests/data/kr6_r900.urdf, joint axes along x and y, extra fixed frames).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_frames, fk_nominal
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.robot.urdf import CONTINUOUS_LIMIT, UrdfError

DATA = Path(__file__).resolve().parents[1] / "data"
URDF = DATA / "kr6_r900.urdf"


def _q(robot, m=100, seed=0):
    return np.random.default_rng(seed).uniform(robot.limits[:, 0], robot.limits[:, 1], (m, robot.n))


@pytest.mark.parametrize("source", [DATA / "kr6_urdf.toml", URDF], ids=["toml", "urdf"])
def test_urdf_and_modified_dh_give_the_same_arm(source):
    """Flange poses equal at 100 random postures (achieved 8e-16 m; tolerance 1e-14), and the
    MCPC model built from the URDF equals them too; joint ranges equal."""
    mdh, urdf = load_robot("kr6-r900"), load_robot(source)
    assert urdf.convention == "urdf" and urdf.dh is None and urdf.joint_types == mdh.joint_types
    np.testing.assert_allclose(urdf.limits, mdh.limits, rtol=0, atol=1e-15)
    q = _q(mdh)
    want = fk_nominal(mdh, q)[:, -1]
    assert np.abs(fk_nominal(urdf, q)[:, -1] - want).max() < 1e-14
    assert np.abs(fk_frames(nominal_mcpc(urdf), q)[:, -1] - want).max() < 1e-14


def test_a_toml_beside_the_urdf_adds_home_and_camera():
    mdh, urdf = load_robot("kr6-r900"), load_robot(DATA / "kr6_urdf.toml")
    assert urdf.name == "kr6-urdf" and urdf.joint_names[0] == "joint_a1"
    np.testing.assert_allclose(urdf.home, mdh.home)
    np.testing.assert_allclose(urdf.T_flange_cam, mdh.T_flange_cam)
    assert urdf.camera_mount_given and mdh.camera_mount_given


def test_direct_urdf_defaults():
    """Root link as base, the leaf six moving joints away (tool0, not the fixed leaf "base") as
    tool; home at joint zero; the camera at the flange."""
    robot = load_robot(URDF)
    assert robot.name == "kr6_r900" and "base_link -> tool0" in robot.description
    np.testing.assert_array_equal(robot.home, np.zeros(6))
    np.testing.assert_array_equal(robot.T_flange_cam, np.eye(4))
    assert not robot.camera_mount_given


def test_a_urdf_robot_is_named_by_its_robot_element(tmp_path):
    """A URDF's ``<robot name>`` names the robot (fk's "model", plan's lines, errors), not the
    file's stem (a new user's rrr.urdf of ``<robot name="rrr3">`` was called "rrr"); a URDF
    naming none keeps the stem."""
    p = tmp_path / "rrr.urdf"
    p.write_text(URDF.read_text().replace('<robot name="kr6_r900"', '<robot name="rrr3"'))
    assert load_robot(p).name == "rrr3"
    p.write_text(URDF.read_text().replace('<robot name="kr6_r900"', '<robot name=""'))
    assert load_robot(p).name == "rrr"


def _variant(tmp_path, old, new, toml_extra=None):
    text = URDF.read_text()
    assert old in text
    p = tmp_path / "arm.urdf"
    p.write_text(text.replace(old, new))
    if toml_extra is None:
        return p
    t = (DATA / "kr6_urdf.toml").read_text().replace('file = "kr6_r900.urdf"', 'file = "arm.urdf"')
    for key, value in toml_extra.items():
        t = t.replace(f'{key} = "{"base_link" if key == "base_link" else "tool0"}"', value)
    tp = tmp_path / "arm.toml"
    tp.write_text(t)
    return tp


def test_continuous_joint_is_revolute_with_wide_limits(tmp_path):
    p = _variant(
        tmp_path,
        '<joint name="joint_a6" type="revolute">',
        '<joint name="joint_a6" type="continuous">',
    )
    robot = load_robot(p)
    assert robot.joint_types[5] == "revolute"
    np.testing.assert_array_equal(robot.limits[5], [-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT])


_A3 = '<joint name="joint_a3" type="revolute">'
_A3_LIMIT = '<limit lower="-2.0943951023931953" upper="2.722713633111154"'


@pytest.mark.parametrize(
    "old,new,links,match,fix",
    [
        (_A3, _A3.replace("revolute", "floating"), {}, r"joint 'joint_a3' is floating", "joint_a3"),
        (_A3, _A3.replace("revolute", "planar"), {}, r"joint 'joint_a3' is planar", "joint_a3"),
        (_A3_LIMIT, '<mimic joint="joint_a2"/>' + _A3_LIMIT, {},
         r"joint 'joint_a3' mimics joint 'joint_a2'", "joint_a3"),
        ("", "", {"tool_link": 'tool_link = "tool9"'},
         r"no link named 'tool9' \(links: base_link,", "[urdf] tool_link"),
        ("", "", {"base_link": 'base_link = "link_3"', "tool_link": 'tool_link = "link_1"'},
         r"link 'link_1' is not below link 'link_3'", "[urdf] base_link"),
    ],
)  # fmt: skip
def test_bad_chains_are_refused_with_a_fix(tmp_path, old, new, links, match, fix):
    p = _variant(tmp_path, old, new, toml_extra=links or None)
    with pytest.raises(UrdfError, match=r"arm.urdf: " + match) as exc:
        load_robot(p)
    assert fix in exc.value.fix


def test_a_two_joint_chain_of_a_urdf_loads(tmp_path):
    """``tool_link = "link_2"``: the first two joints alone, e.g. a positioner (before: refused as
    fewer than 3 joints)."""
    p = _variant(tmp_path, "", "", toml_extra={"tool_link": 'tool_link = "link_2"'})
    (tmp_path / "arm.toml").write_text(
        (tmp_path / "arm.toml")
        .read_text()
        .replace("home_deg = [35.0, -77.0, 113.0, 0.0, 54.0, 0.0]", "")
    )
    robot = load_robot(p)
    full = load_robot(_variant(tmp_path, "", ""))
    assert robot.n == 2 and robot.joint_names == full.joint_names[:2]
    q = np.radians([[20.0, -30.0]])
    # link_2's origin is joint 2's frame of the whole chain (whose axes follow the joint axis)
    np.testing.assert_allclose(
        fk_nominal(robot, q)[0, -1, :3, 3],
        fk_nominal(full, np.c_[q, np.zeros((1, 4))])[0, 1, :3, 3],
        atol=1e-12,
    )


def test_ambiguous_tool_link_asks_for_a_name(tmp_path):
    extra = (
        '<link name="camera_link"/>\n  <joint name="link_6-camera" type="fixed">\n'
        '    <parent link="link_6"/>\n    <child link="camera_link"/>\n  </joint>\n</robot>'
    )
    p = _variant(tmp_path, "</robot>", extra)
    with pytest.raises(UrdfError, match=r"leaf links camera_link, tool0 all end 6 moving") as exc:
        load_robot(p)
    assert "tool_link" in exc.value.fix


def test_unreadable_urdf(tmp_path):
    p = tmp_path / "broken.urdf"
    p.write_text("solid cube\nfacet normal 0 0 1\n")
    with pytest.raises(InputError, match="broken.urdf: not a URDF: not XML"):
        load_robot(p)


def _tilted_variant(tmp_path) -> Path:
    """The fixture with tilted joint origins and axes (no axis along x, y or z), a negative axis
    and a prismatic joint: what a general URDF may hold."""
    text = URDF.read_text()
    edits = [
        ('<origin xyz="0 0 0.2" rpy="0 0 0"/>', '<origin xyz="0.01 -0.02 0.2" rpy="0.1 -0.2 0.3"/>'),
        ('<origin xyz="0.455 0 0" rpy="0 0 0"/>', '<origin xyz="0.455 0.01 0" rpy="0 0.2 0"/>'),
        ('<origin xyz="0 0 0.035" rpy="0 0 0"/>', '<origin xyz="0 0 0.035" rpy="0.3 0 -0.1"/>'),
        ('<joint name="joint_a4" type="revolute">', '<joint name="joint_a4" type="prismatic">'),
        ('<limit lower="-3.2288591161895095" upper="3.2288591161895095"', '<limit lower="-0.1" upper="0.1"'),
    ]  # fmt: skip
    for old, new in edits:
        assert old in text
        text = text.replace(old, new, 1)
    axes = iter(["0.6 0 0.8", "0 -1 0", "0.3 0.9 0.316", "1 0 0", "0 1 0", "-0.48 0.6 0.64"])
    out = []
    for line in text.splitlines():
        if line.strip().startswith("<axis "):
            line = f'    <axis xyz="{next(axes)}"/>'
        out.append(line)
    p = tmp_path / "tilted.urdf"
    p.write_text("\n".join(out))
    return p


def test_general_urdf_chain_matches_yourdfpy_forward_kinematics(tmp_path):
    """Tilted origins and axes, a prismatic joint: the chain's flange equals yourdfpy's own
    forward kinematics of tool0 in base_link at 30 random postures (achieved ~1e-15; tolerance
    1e-13)."""
    import yourdfpy

    p = _tilted_variant(tmp_path)
    robot = load_robot(p)
    assert robot.joint_types[3] == "prismatic"
    urdf = yourdfpy.URDF.load(str(p), load_meshes=False)
    assert list(urdf.actuated_joint_names) == list(robot.joint_names)
    q = _q(robot, 30, seed=4)
    ours = fk_nominal(robot, q)[:, -1]
    mcpc = fk_frames(nominal_mcpc(robot), q)[:, -1]
    for qi, T, M in zip(q, ours, mcpc):
        urdf.update_cfg(qi)
        want = urdf.get_transform("tool0", "base_link")
        assert np.abs(T - want).max() < 1e-13
        assert np.abs(M - want).max() < 1e-13


LOOP = (
    '<joint name="loop_back" type="revolute">\n    <parent link="link_4"/>\n'
    '    <child link="link_2"/>\n    <axis xyz="0 0 1"/>\n'
    '    <limit lower="-1" upper="1" effort="1" velocity="1"/>\n  </joint>\n</robot>'
)


@pytest.mark.parametrize("links", [None, {"tool_link": 'tool_link = "tool0"'}])
def test_a_kinematic_loop_is_refused_naming_the_joint(tmp_path, links):
    """#33: a joint from a child link back to an ancestor made `selfcal fk` run for ever (still
    running after 300 s). A URDF is a tree: the second joint into a link is named."""
    p = _variant(tmp_path, "</robot>", LOOP, toml_extra=links)
    with pytest.raises(UrdfError, match=r"arm.urdf: joint 'loop_back' makes link 'link_2' the "
                                        r"child of a second joint \('joint_a2'") as exc:  # fmt: skip
        load_robot(p)
    assert "a URDF is a tree" in str(exc.value) and "loop_back" in exc.value.fix


def test_a_cycle_without_a_root_is_refused(tmp_path):
    """Every link a child (the loop closes on the root): no root and a cycle, named."""
    root = (
        '<joint name="to_root" type="fixed">\n    <parent link="tool0"/>\n'
        '    <child link="base_link"/>\n  </joint>\n</robot>'
    )
    p = _variant(tmp_path, "</robot>", root)
    with pytest.raises(UrdfError, match=r"joint 'to_root' .* a kinematic loop"):
        load_robot(p)


def test_plain_text_as_urdf_is_one_clear_error(tmp_path, capfd, caplog):
    """#33: a plain-text file given as URDF printed a TypeError's text and two lxml lines before
    the error; now one line naming the file, exit 2."""
    from selfcal.cli.main import main

    p = tmp_path / "notes.urdf"
    p.write_text("this robot has six joints\nand a camera\n")
    assert main(["fk", "--robot", str(p), "--joints", "0,0,0,0,0,0"]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("selfcal: error: ") and str(p) in err
    assert "not a URDF" in err and "TypeError" not in err
    assert not [r for r in caplog.records if r.name.startswith("yourdfpy")]  # no parser lines


@pytest.mark.parametrize(("old", "new"), [('xyz="0.455 0 0"', 'xyz="nan 0 0"'),
                                          ('<axis xyz="0 1 0"/>', '<axis xyz="0 inf 0"/>')])  # fmt: skip
def test_non_finite_origins_and_axes_are_refused(tmp_path, old, new):
    """Found by the fuzz test (#33): an origin of NaN gave a chain of NaN without a word."""
    p = _variant(tmp_path, old, new)
    with pytest.raises(UrdfError, match=r"arm.urdf: joint 'joint_a\d': <(origin|axis xyz)> must"):
        load_robot(p)


def test_origins_too_large_for_floating_point_are_refused(tmp_path):
    """The fuzz test's find: finite origins of 1.8e308 m composed to an infinite flange pose and
    loaded as a robot."""
    text = (Path(__file__).resolve().parents[1] / "data" / "kr6_r900.urdf").read_text()
    i = text.index("<origin", text.index('<joint name="flange-tool0"'))
    text = text[:i] + '<origin xyz="1.7976931348623155e+308 0 1.7976931348623155e+308" rpy="3.1 -1.5 0"' \
        + text[text.index("/>", i):]  # fmt: skip
    (tmp_path / "arm.urdf").write_text(text)
    with pytest.raises(UrdfError, match="does not compose to finite transforms"):
        load_robot(tmp_path / "arm.urdf")


@pytest.mark.parametrize("value", ['xyz="nan 0 0.2" rpy="0 0 0"', 'xyz="0 0 0.2" rpy="inf 0 inf"'])
def test_a_non_finite_origin_is_refused_without_a_numpy_warning(tmp_path, value):
    """A joint's <origin> of nan / inf is refused naming the joint, and loading it raises no
    RuntimeWarning from the URDF parser's transforms (trimesh's "invalid value encountered in
    dot", which leaked from the URDF fuzz test into the default tier's summary, session 25)."""
    import warnings

    p = _variant(tmp_path, '<origin xyz="0 0 0.2" rpy="0 0 0"/>', f"<origin {value}/>")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with pytest.raises(UrdfError, match=r"joint_a1.*<origin> must be finite numbers"):
            load_robot(p)
    assert [str(w.message) for w in seen] == []
