"""selfcal.benchmarks.timing.render runs, with the per-stage breakdown (it crashed: the renderer's
rectangle became one per camera, ``_rects``, and the breakdown still read ``_rect``)."""

from __future__ import annotations

import re

from selfcal.benchmarks.timing import render as benchmark_render


def test_breakdown_prints_each_stage(capsys):
    benchmark_render.main(["--n", "2", "--width", "160", "--height", "120", "--breakdown"])
    out = capsys.readouterr().out
    assert re.search(r"160x120 samples=\d+ .* median [\d.]+ ms per stereo pair", out), out
    stages = re.findall(r"(\w[\w+]*) ([\d.]+) ms", out.splitlines()[-1])
    assert [s for s, _ in stages] == ["update_scene", "mjr_render", "readPixels", "flip+copy"]
