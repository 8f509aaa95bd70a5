"""Targets (selfcal.target): the feature-id mapping of the ArUco field and its detection."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from selfcal.errors import InputError
from selfcal.target import (
    CORNERS_PER_MARKER,
    ArucoField,
    Features,
    Target,
    feature_id,
    marker_corner,
    marker_features,
    markers_to_features,
)
from selfcal.target.aruco_detect import detect_markers


@given(st.integers(0, 10**6), st.integers(0, CORNERS_PER_MARKER - 1))
def test_feature_id_round_trip(marker, corner):
    fid = feature_id(marker, corner)
    assert marker_corner(fid) == (marker, corner)
    assert fid in marker_features(marker).tolist()
    assert marker_features(marker)[corner] == fid


def test_feature_ids_are_distinct_and_vectorised():
    markers = np.arange(50)
    ids = marker_features(markers)
    assert ids.shape == (50, CORNERS_PER_MARKER)
    assert len(np.unique(ids)) == ids.size
    mk, cn = marker_corner(ids.ravel())
    np.testing.assert_array_equal(mk, np.repeat(markers, CORNERS_PER_MARKER))
    np.testing.assert_array_equal(cn, np.tile(np.arange(CORNERS_PER_MARKER), 50))
    np.testing.assert_array_equal(feature_id(mk, cn), ids.ravel())


def test_aruco_field_detects_features_with_the_mapping():
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    img = np.full((240, 320), 255, np.uint8)
    img[40:120, 40:120] = cv2.aruco.generateImageMarker(d, 7, 80, borderBits=1)
    img[100:180, 180:260] = cv2.aruco.generateImageMarker(d, 2, 80, borderBits=1)
    field = ArucoField("DICT_4X4_50")
    assert isinstance(field, Target)
    feats = field.detect(img)
    markers = detect_markers(img, "DICT_4X4_50")
    assert sorted(markers) == [2, 7]
    ref = markers_to_features(markers)
    np.testing.assert_array_equal(feats.ids, ref.ids)
    np.testing.assert_array_equal(feats.uv, ref.uv)
    for mid, corners in markers.items():
        np.testing.assert_array_equal(feats.uv[np.isin(feats.ids, marker_features(mid))], corners)
    assert np.isnan(field.points(feats.ids)).all()  # positions unknown: estimated
    assert len(field.detect(np.full((60, 80), 255, np.uint8))) == 0


def test_features_validate_lengths():
    f = Features([1, 2], np.zeros((2, 2)))
    assert len(f) == 2 and f.ids.dtype == np.int64
    with pytest.raises(ValueError, match="3 ids but 2"):
        Features([1, 2, 3], np.zeros((2, 2)))


def test_markers_to_features_stacks_markers_in_order_and_names_a_wrong_one():
    rng = np.random.default_rng(2)
    markers = {mid: rng.uniform(0, 640, (4, 2)) for mid in (31, 3, np.int64(12))}
    f = markers_to_features(markers)
    np.testing.assert_array_equal(f.ids, np.concatenate([marker_features(m) for m in (31, 3, 12)]))
    np.testing.assert_array_equal(f.uv, np.concatenate(list(markers.values())))
    assert f.ids.dtype == np.int64 and len(markers_to_features({})) == 0
    with pytest.raises(InputError, match=r"marker 12 in view 4: corners must have shape \(4, 2\)"):
        markers_to_features({**markers, 12: np.zeros((4, 3))}, "view 4")
