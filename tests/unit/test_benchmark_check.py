"""The speed benchmark's loud failure (#17): a figure more than 1.3x off the README's block is
named, one within it is not."""

from __future__ import annotations

import re

from selfcal.benchmarks.speed.table import TOLERANCE, check, figures_of, readme_block


def _scaled(block: str, row: str, factor: float) -> str:
    """``block`` with the seconds of the row starting ``| row`` multiplied by ``factor``."""

    def f(m: re.Match) -> str:
        return f"{m.group(1)}{float(m.group(2)) * factor:.4f} |"

    return re.sub(rf"^(\| {re.escape(row)}.*? \| )([0-9.]+) \|$", f, block, flags=re.M)


def test_figures_more_than_the_tolerance_off_are_named():
    stated = readme_block()
    figures = figures_of(stated)
    assert len(figures) >= 8  # the README's block is there and parses
    assert check(stated, stated) == []
    new = _scaled(stated, "`selfcal run`", 1.38)
    new = _scaled(new, "`selfcal --help`", 1.2)
    bad = check(new, stated)
    assert len(bad) == 1 and bad[0].startswith("`selfcal run`") and "1.38x" in bad[0]
    faster = _scaled(stated, "`selfcal fk", 1 / (TOLERANCE * 1.05))
    assert [b for b in check(faster, stated) if b.startswith("`selfcal fk")]


def test_selfcal_run_is_timed_into_a_new_folder_each_time(tmp_path):
    """run_seconds: ``--run-repeat`` runs, each into its own folder (a second run into the same
    one would fail here), the median of their wall and CPU seconds."""
    import pathlib
    import sys

    from selfcal.benchmarks.speed.measure import beside_a_busy_process, run_seconds

    fake = [sys.executable, "-c", "import pathlib, sys; pathlib.Path(sys.argv[-1]).mkdir()"]
    wall, cpu = run_seconds(fake, tmp_path / "run", 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run-0", "run-1", "run-2"]
    assert 0.0 < cpu and 0.0 < wall < 60.0
    loaded = beside_a_busy_process(lambda: run_seconds(fake, tmp_path / "loaded", 1))
    assert pathlib.Path(tmp_path / "loaded-0").is_dir() and len(loaded) == 2
