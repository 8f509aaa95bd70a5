"""``python -m selfcal.benchmarks.board.montecarlo [--draws 30] [--jobs 2]``: an alias of
``selfcal montecarlo scenarios/mono-charuco.toml --draws N --out DIR`` (one camera + ChArUco on
the analytic path against the board route's Cramer-Rao bound, :mod:`selfcal.studies.montecarlo.run` with
:mod:`selfcal.studies.montecarlo.board`), kept for the commands written before ``selfcal montecarlo``
took board scenarios. Prints the summary (``DIR/summary.md``).
"""

from __future__ import annotations

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.config.scenario import scenarios_dir

__all__ = ["MONO_CHARUCO", "main"]

MONO_CHARUCO = scenarios_dir() / "mono-charuco.toml"


def main(argv: list[str] | None = None) -> int:
    """Parse the alias's arguments and run ``selfcal montecarlo`` on the board scenario."""
    from selfcal.cli.main import main as selfcal

    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument("--config", default=str(MONO_CHARUCO), help="a board scenario")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="runs/montecarlo-board")
    a = ap.parse_args(argv)
    return selfcal(["montecarlo", a.config, "--draws", str(a.draws), "--jobs", str(a.jobs),
                    "--out", a.out])  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
