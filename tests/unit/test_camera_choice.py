"""``--camera-model`` / ``--free`` per camera (selfcal.importing.camera_choice): parsing, spreading, errors."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from selfcal.errors import InputError
from selfcal.importing.camera_choice import ALL, camera_options, for_cameras, free_value, per_camera

CAMS = ["cam0", "cam1", "cam2"]


def test_a_bare_value_applies_to_every_camera_not_named():
    models, frees = camera_options(["opencv", "cam1=fisheye"],
                                   ["cam1=fx,mu,cx,cy,k1,k2,k3,k4"], CAMS, "--images")  # fmt: skip
    assert models == {"cam0": "opencv", "cam1": "fisheye", "cam2": "opencv"}
    assert frees == {"cam1": ("fx", "mu", "cx", "cy", "k1", "k2", "k3", "k4")}


def test_no_option_leaves_every_camera_to_its_default():
    assert camera_options(None, None, CAMS, "--images") == ({}, {})


def test_todays_single_values_are_unchanged():
    models, frees = camera_options(["pinhole"], ["fx, mu,cx"], CAMS, "--images")
    assert models == dict.fromkeys(CAMS, "pinhole")
    assert frees == dict.fromkeys(CAMS, ("fx", "mu", "cx"))


@pytest.mark.parametrize(
    ("models", "frees", "match"),
    [
        (
            ["cam7=fisheye"],
            None,
            r"--camera-model names camera\(s\) cam7, but the --images "
            r"cameras are cam0, cam1, cam2",
        ),  # fmt: skip
        (None, ["cam7=fx"], r"--free names camera\(s\) cam7"),
        (["fishy"], None, r"--camera-model 'fishy'.*pinhole, opencv, fisheye"),
        (["cam1=fishy"], None, r"--camera-model 'fishy'"),
        (["opencv", "pinhole"], None, "given twice for every camera"),
        (["cam1=opencv", "cam1=pinhole"], None, "given twice for camera cam1"),
        (["cam 1=opencv"], None, "camera name 'cam 1'"),
    ],
)
def test_bad_options_are_named(models, frees, match):
    with pytest.raises(InputError, match=match):
        camera_options(models, frees, CAMS, "--images")


@given(
    named=st.dictionaries(st.sampled_from(CAMS), st.sampled_from(["pinhole", "opencv"])),
    bare=st.none() | st.just("fisheye"),
)
def test_every_camera_gets_its_own_value_else_the_bare_one(named, bare):
    given_ = dict(named) | ({} if bare is None else {ALL: bare})
    out = for_cameras(given_, CAMS, "--camera-model", "--images")
    for c in CAMS:
        assert out.get(c) == named.get(c, bare)


def test_a_free_list_is_split_on_commas():
    assert per_camera(["cam1= fx,mu ,,cx"], "--free", free_value) == {"cam1": ("fx", "mu", "cx")}
