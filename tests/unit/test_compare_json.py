"""The golden-file comparison itself can fail: a changed number, a missing key, a changed string."""

from conftest import compare_json


def test_equal_within_tolerance_passes():
    a = {"x": 1.0, "y": [1e-12, "s"], "seconds": 3.0}
    b = {"x": 1.0 + 5e-7, "y": [0.0, "s"], "seconds": 9.0, "new": 1}
    assert compare_json(a, b, rtol=1e-6, atol=1e-9) == []


def test_differences_are_named():
    a = {"x": 1.0, "y": [1.0, "s"], "z": {"w": True}}
    b = {"x": 1.0 + 2e-6, "y": [1.0, "t"], "z": {}}
    problems = compare_json(a, b, rtol=1e-6, atol=1e-9)
    assert [p.split(":")[0] for p in problems] == [".x", ".y[1]", ".z.w"]
