"""The speed benchmark's loud failure (#17): a figure more than 1.3x off the README's block is
named, one within it is not."""

from __future__ import annotations

import re

from selfcal.benchmarks.speed import TOLERANCE, check, figures_of, readme_block


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
