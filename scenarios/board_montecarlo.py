"""``python -m scenarios.board_montecarlo [--draws 30] [--jobs 2]``: an alias of
``selfcal montecarlo scenarios/mono-charuco.toml --draws N --out DIR`` (one camera + ChArUco on
the analytic path against the board route's Cramer-Rao bound, :mod:`scenarios.montecarlo` with
:mod:`scenarios.montecarlo_board`), kept for the commands written before ``selfcal montecarlo``
took board scenarios. Prints the summary (``DIR/summary.md``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["MONO_CHARUCO", "main"]

MONO_CHARUCO = Path(__file__).resolve().with_name("mono-charuco.toml")


def main(argv: list[str] | None = None) -> int:
    """Parse the alias's arguments and run ``selfcal montecarlo`` on the board scenario."""
    from scenarios.cli import main as selfcal

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument("--config", default=str(MONO_CHARUCO), help="a board scenario")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="runs/montecarlo-board")
    a = ap.parse_args(argv)
    return selfcal(["montecarlo", a.config, "--draws", str(a.draws), "--jobs", str(a.jobs),
                    "--out", a.out])  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
