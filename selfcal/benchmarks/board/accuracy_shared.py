"""Benchmark: whether two robots' board accuracy draws of one seed share their chance (#29).

The board accuracy Monte Carlo (:mod:`selfcal.benchmarks.board.accuracy`) draws every robot
with the same seeds, and a seed's corner noise is the same stream of standard normals for every
robot (:func:`selfcal.acquisition.backends.open_robot`: ``default_rng(seed + 7919)``), laid on
other corners of other views. When two robots' rows of the same seeds both sit at the far end
of a right bound's spread (the orientation's over-coverage on seeds 1-90), that is one chance
if their draws' errors go together and two if they do not. Per seed, both robots' draws
(:func:`selfcal.benchmarks.board.accuracy_parts.kept_draw`) and over the seeds the rank
correlation of each draw's orientation error against its prediction at its first inside joint
vector (:func:`selfcal.benchmarks.board.accuracy_parts.first_point`: the integral transform
``u`` and the whitened error) and the correlation of the camera's shared free parameters'
errors in their predicted standard deviations (the parameters the camera mount's tilt trades
with). Independent draws give correlations within about ``+-1.645 / sqrt(d - 1)`` for ``d``
seeds (90 %); ``--noise-offset N`` draws the second robot's noise with the seed ``N`` higher
(its truths and postures kept): a control whose draws share no noise.

Run: ``uv run python -m selfcal.benchmarks.board.accuracy_shared [--robots er4u-paper,ur5e]
[--noise-px 0.2] [--draws 90] [--first-seed 1] [--noise-offset N] [--jobs 1] [--keep DIR]``.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy.stats import pearsonr, spearmanr

from selfcal.benchmarks.board.accuracy_parts import draw_options, first_point, kept_draw
from selfcal.benchmarks.doc_blocks import code_version
from selfcal.benchmarks.pool import map_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.errors import UsageError
from selfcal.threads import limit_threads

__all__ = ["main", "shared", "shared_lines"]


def shared(a: list[dict], b: list[dict]) -> dict:
    """The correlations over the seeds of two robots' draws ``a`` and ``b``
    (:func:`selfcal.benchmarks.board.accuracy_parts.draw_parts`, the same seeds in the same
    order; a seed with a failed draw left out): ``seeds``; ``u`` and ``whitened`` the Spearman
    correlation and its p of the two robots' :func:`first_point` values; ``camera`` by name of
    the free camera parameters both draws have, the Pearson correlation and its p of their errors
    in predicted standard deviations; ``null`` the 90 % half-range of a correlation of
    independent draws, ``1.645 / sqrt(seeds - 1)``."""
    pairs = [(g, h) for g, h in zip(a, b, strict=True) if g["status"] == h["status"] == "ok"]
    d = len(pairs)
    if d < 4:
        raise UsageError(f"{d} seeds with both draws ok: at least 4 are needed for a correlation")
    f = np.array([[*first_point(g), *first_point(h)] for g, h in pairs])
    out: dict = {"seeds": d, "null": 1.645 / np.sqrt(d - 1)}
    for k, name in enumerate(("u", "whitened")):
        r = spearmanr(f[:, k], f[:, 2 + k])
        out[name] = (float(r.statistic), float(r.pvalue))
    out["camera"] = {}
    g0, h0 = pairs[0]
    cam_a = list(g0["names"])[g0["J"].shape[2] :]  # the camera's free parameters come last
    cam_b = list(h0["names"])[h0["J"].shape[2] :]
    for name in (n for n in cam_a if n in cam_b):
        i, j = list(g0["names"]).index(name), list(h0["names"]).index(name)
        za = [g["error"][i] / np.sqrt(g["cov"][i, i]) for g, _ in pairs]
        zb = [h["error"][j] / np.sqrt(h["cov"][j, j]) for _, h in pairs]
        r = pearsonr(za, zb)
        out["camera"][name] = (float(r.statistic), float(r.pvalue))
    return out


def shared_lines(s: dict, title: str) -> list[str]:
    """The lines :func:`main` prints of a :func:`shared`."""
    cam = ", ".join(f"{n} {r:+.2f} (p {p:.2f})" for n, (r, p) in s["camera"].items())
    return [
        f"{title}: {s['seeds']} seeds; independent draws' correlations lie within "
        f"+-{s['null']:.2f} (90 %)",
        f"orientation at the first inside point, Spearman: u {s['u'][0]:+.2f} (p "
        f"{s['u'][1]:.2f}), whitened error {s['whitened'][0]:+.2f} (p {s['whitened'][1]:.2f})",
        f"camera parameters' errors in their standard deviations, Pearson: {cam}",
    ]


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="er4u-paper,ur5e",
                    help="two robots (default er4u-paper,ur5e)")  # fmt: skip
    draw_options(ap, 90)
    ap.add_argument("--noise-offset", type=int, metavar="N",
                    help="draw the second robot's noise with the seed N higher (a control)")  # fmt: skip
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run both robots' draws (one BLAS thread per process) and print the correlations."""
    limit_threads(1)
    a = _arguments(argv)
    robots = a.robots.split(",")
    if len(robots) != 2:
        raise UsageError(f"--robots {a.robots!r}: give two robots, comma-separated")
    seeds = range(a.first_seed, a.first_seed + a.draws)
    code = code_version()
    first = [(robots[0], a.noise_px, s, None, a.keep, code) for s in seeds]
    second = [(robots[1], a.noise_px, s, None, a.keep, code) if a.noise_offset is None
              else (robots[1], a.noise_px, s + a.noise_offset, s, a.keep, code)
              for s in seeds]  # fmt: skip
    got = map_jobs(kept_draw, first + second, a.jobs)
    noise = ("the same seed's noise" if a.noise_offset is None
             else f"{robots[1]}'s noise from the seed {a.noise_offset} higher")  # fmt: skip
    title = (f"{robots[0]} against {robots[1]}, fits {a.noise_px:g} px, seeds {seeds.start}-"
             f"{seeds.stop - 1} ({noise})")  # fmt: skip
    print("\n".join(shared_lines(shared(got[: len(first)], got[len(first) :]), title)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
