"""The hand-eye comparison with OpenCV 4.x (selfcal.benchmarks.handeye.poses) on a tiny case:
without noise every one of OpenCV's seven methods and ours predict the held-out corners exactly,
in both setups, so the benchmark hands each method its frames as OpenCV documents them; the
table and its docs block are written. Slow: it makes OpenCV 4.x's environment with uv (a
download the first time)."""

from __future__ import annotations

import shutil

import pytest

from selfcal.benchmarks.doc_blocks import write_block
from selfcal.benchmarks.handeye import poses as hp

pytestmark = pytest.mark.slow


def test_noise_free_every_method_predicts_the_held_out_corners(tmp_path):
    if shutil.which("uv") is None:
        pytest.skip("uv makes OpenCV 4.x's environment")
    splits = [hp.synthetic_split(s, 0.0, 0.0, 0.0, 3, n_train=8, n_held=3)
              for s in ("eye-in-hand", "eye-to-hand")]  # fmt: skip
    rows, version = hp.run(splits)
    assert version.startswith("OpenCV 4.")
    for r in rows:
        for m in hp.OURS:
            assert r[m] < 1.2e-11, (r["name"], m, r[m])  # measured: at most 3.7e-12 px
        for m in hp.OPENCV:  # OpenCV's calibrateCamera takes float32 corners
            assert r[m] < 2.5e-3, (r["name"], m, r[m])  # measured: at most 8.3e-4 px (Li)
    doc = tmp_path / "doc.md"
    doc.write_text(
        "x\n<!-- benchmark_handeye_poses: begin -->\nold\n<!-- benchmark_handeye_poses: end -->\n"
    )
    write_block(doc, hp.table(rows, version), "benchmark_handeye_poses")
    text = doc.read_text()
    assert "\nold\n" not in text and "| eye-to-hand, 0 px | 1 |" in text
