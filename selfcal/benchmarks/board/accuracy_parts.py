"""Benchmark: which parameters' predicted covariance the board calibration's errors realise (#29).

The board accuracy Monte Carlo (:mod:`selfcal.benchmarks.board.accuracy`) pools the predicted
95 % bound's coverage of the flange's true error. This script looks inside one of its rows:
per draw (the same draws, :func:`selfcal.benchmarks.board.accuracy_draw.calibrated`) the
calibration's error in every minimal parameter (against the true chain in the board frame, the
calibration's joint offsets: :func:`selfcal.benchmarks.board.accuracy_draw.true_chain`) and in
the camera's free parameters (against the simulator's camera), each in units of its predicted
standard deviation (the accuracy block's ``covariance_si`` and ``camera_covariance_si``): ``z``.
A right covariance gives ``z`` a mean near 0 and a mean square near 1 over the draws (the mean
square of ``d`` draws spreads by about ``sqrt(2 / d)``).

The orientation's part: at the draw's inside-region joint vectors (:data:`COUNT`, as the
Monte Carlo's) the predicted orientation covariance ``J C J^T`` is split into the parameter
covariance's directions that carry it (the eigenvectors of ``C^1/2 W C^1/2``, ``W`` the mean of
``J^T J`` of the orientation rows): each direction's share of the predicted orientation
variance, its largest parameters, and the mean square of the draws' errors along it in its
predicted standard deviations. Besides, the realised mean square orientation error over the
predicted one, and how far the first-order carriage ``J dp`` of the parameter error is from the
true orientation error (the same frame and convention when near 0).

The orientation bound itself (:func:`bound_check`): the 95 % bound of the orientation error's
norm (:func:`selfcal.kinematics.tool_error.norm_quantile` of ``J C J^T``, the covariance alone,
as the Monte Carlo's column "orientation, covariance alone" at the inside region) against the
true errors: the pooled coverage; each draw's probability integral transform at the first inside
joint vector, ``u = P(|x| <= |e|)`` for ``x`` from the prediction (Satterthwaite's chi-square, the
bound's own), uniform on 0-1 over the draws for a right prediction whatever the draws' truths,
so its mean (0.5 +- ``sqrt(1 / 12 d)``), the Kolmogorov-Smirnov test of it and the count of draws
beyond the bound there (``u > 0.95``: binomial, ``d`` draws at 5 %) say whether the bound is
too wide with every draw's whole error, not only whether it fell inside; the realised over the
predicted mean square with a bootstrap 90 % range over the draws; and the Satterthwaite
quantile against the exact one (each draw's covariance sampled).

``--fixed-truth SEED``: every draw keeps the truth and postures of ``SEED`` and draws only new
pixel noise (seeds ``--first-seed``...): the spread over the draws is the pixel noise's part
alone, the mean the joint read-back's (the same rounded counts in every draw). ``--noise-offset
N``: every draw keeps its own seed's truth and postures and draws its pixel noise with the seed
``N`` higher (other noise on the same truths: whether what a set of draws shows sits with its
truths or with its noise). ``--keep DIR``:
each draw's result is kept in ``DIR`` (one ``.npz`` a draw, named by robot, noise, seed and fixed
truth, holding the code that drew it: :func:`selfcal.benchmarks.doc_blocks.code_version`) and
read from there when it is already in it and was drawn by the code checked out, a clean commit
(the numbers the same: each draw is seeded); else it is drawn again and kept in its place.

Run: ``uv run python -m selfcal.benchmarks.board.accuracy_parts [--robot er4u-paper]
[--noise-px 0.2] [--draws 20] [--first-seed 1] [--fixed-truth SEED | --noise-offset N] [--jobs 1]
[--keep DIR]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import binom, chi2, kstest

from selfcal.benchmarks.board.accuracy_draw import (
    calibrated,
    draw_sample,
    scenario,
    simulated,
    true_chain,
)
from selfcal.benchmarks.doc_blocks import code_version
from selfcal.benchmarks.pool import map_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.accuracy import board_error_model_from_json
from selfcal.camera.spec import values_by_name
from selfcal.errors import UsageError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import param_is_angle, param_names
from selfcal.kinematics.tool_error import norm_quantile
from selfcal.threads import limit_threads

__all__ = [
    "bound_check",
    "bound_lines",
    "draw_options",
    "draw_parts",
    "directions",
    "first_point",
    "kept_draw",
    "main",
    "orientation_covariance",
    "table",
]

DIRECTIONS = 4
"""The orientation covariance's directions :func:`table` lists (the ER-4u's first two carry
about 90 % of it)."""


def draw_parts(args: tuple) -> dict:
    """One draw (``robot``, corner noise ``sigma_px`` px, ``seed``, the fixed truth's seed or
    None): by key ``names`` the parameters (minimal, then the camera's free ones), ``error``
    their calibration errors (rad, m; the camera's in its units), ``cov`` (k, k) their predicted
    covariance with the cross block, ``J`` (m, 3, p) the orientation rows of the inside
    region's Jacobian over the minimal parameters (rad per unit), ``e_rot`` (m, 3) the true
    orientation errors there (rad, rotation vectors, board frame); ``status``."""
    robot, sigma_px, seed, truth_seed = args
    try:
        s = (scenario(robot, sigma_px, seed) if truth_seed is None
             else scenario(robot, sigma_px, truth_seed, noise_seed=seed))  # fmt: skip
        setup = simulated(s, "fits")
        cal, truth, _ = calibrated(s, setup)
        block = cal.accuracy
        assert block is not None
        em = board_error_model_from_json(block, cal.model, "calibration.json")
        true_b = true_chain(cal, truth)
        dp = (cal.model.params - true_b.params).reshape(-1)[em.columns]
        ang = param_is_angle(em.columns)
        dp = np.where(ang, (dp + np.pi) % (2 * np.pi) - np.pi, dp)  # an angle's 2 pi is no error
        cam = cal.cameras[0]
        est, true = values_by_name(cam), values_by_name(setup.intrinsics)
        dc = np.array([est[n] - true[n] for n in cam.free])
        cross = np.asarray(block["camera_cross_si"])
        cam_cov = np.asarray(block["camera_covariance_si"])
        cov = np.block([[em.covariance, cross], [cross.T, cam_cov]])
        q = draw_sample(cal, seed if truth_seed is None else truth_seed).inside
        tip = np.asarray(block["T_tool_point_si"])
        R_est = (fk_tool(cal.model, q) @ tip)[:, :3, :3]
        R_true = (fk_tool(true_b, q) @ tip)[:, :3, :3]
        e_rot = Rotation.from_matrix(R_est @ np.swapaxes(R_true, 1, 2)).as_rotvec()
        return {"status": "ok", "names": [*param_names(em.columns), *cam.free],
                "error": np.r_[dp, dc], "cov": cov, "J": em.jacobian(q)[:, 3:], "e_rot": e_rot}  # fmt: skip
    except Exception as exc:  # noqa: BLE001 - a benchmark counts failed draws
        return {"status": f"failed: {type(exc).__name__}: {str(exc)[:200]}"}


def _root(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``C^1/2`` (k, r) and its pseudo-inverse (r, k) over the eigenvalues above 1e-14 of the
    largest."""
    w, V = np.linalg.eigh(C)
    keep = w > w.max() * 1e-14
    return V[:, keep] * np.sqrt(w[keep]), (V[:, keep] / np.sqrt(w[keep])).T


def directions(g: dict) -> dict:
    """One draw's orientation directions (module docstring): ``share`` (r,) of the predicted
    mean orientation variance, ``z`` (r,) the error along each in its standard deviations,
    ``load`` (p, r) each direction's unit parameter loading (minimal parameters), largest
    share first; ``ratio`` the realised over the predicted mean square orientation error,
    ``linear`` the RMS of ``J dp`` minus the true error over the true error's RMS."""
    J, e = g["J"], g["e_rot"]
    p = J.shape[2]
    C, dp = g["cov"][:p, :p], g["error"][:p]
    root, inv = _root(C)
    W = np.mean(np.swapaxes(J, 1, 2) @ J, axis=0)
    mu, U = np.linalg.eigh(root.T @ W @ root)
    mu, U = mu[::-1], U[:, ::-1]
    d = root @ U
    lin = np.einsum("mij,j->mi", J, dp)
    return {
        "share": mu / mu.sum(),
        "z": U.T @ (inv @ dp),
        "load": d / np.linalg.norm(d, axis=0),
        "ratio": float(np.mean(np.sum(e**2, axis=1)) / mu.sum()),
        "linear": float(np.sqrt(np.mean((lin - e) ** 2) / np.mean(e**2))),
    }


def kept_draw(args: tuple) -> dict:
    """:func:`draw_parts` of ``args[:4]``, kept in the folder ``args[4]`` (one ``.npz`` a draw;
    None: not kept) with the code that drew it, ``args[5]`` (:func:`code_version`), and read from
    there when it is already in it, drawn by that same code, a clean commit (a draw of other
    code, of a code with uncommitted changes or of none recorded is drawn again and kept in its
    place: the same name need not be the same numbers)."""
    robot, sigma_px, seed, truth_seed, keep, code = args
    if keep is None:
        return draw_parts((robot, sigma_px, seed, truth_seed))
    path = Path(keep) / f"{robot}_{sigma_px:g}px_seed{seed}_truth{truth_seed}.npz"
    clean = bool(code) and not code.endswith("+changes")
    if path.exists() and clean:
        with np.load(path, allow_pickle=False) as z:
            g = {k: z[k] for k in z.files}
        if "code" in g and str(g["code"]) == code:
            g["status"], g["names"] = str(g["status"]), [str(n) for n in g["names"]]
            g["code"] = code
            return g
    g = draw_parts((robot, sigma_px, seed, truth_seed)) | {"code": code or ""}
    path.parent.mkdir(parents=True, exist_ok=True)
    # Any: numpy's stub would match a key to savez's allow_pickle (no key is named so)
    arrays: dict[str, Any] = {k: np.asarray(v) for k, v in g.items()}
    np.savez(path, **arrays)
    return g


def orientation_covariance(g: dict) -> np.ndarray:
    """(m, 3, 3) rad^2 a draw's (:func:`draw_parts`) predicted orientation covariance at its
    inside joint vectors, ``J C J^T`` (the covariance alone, board frame)."""
    J = g["J"]
    p = J.shape[2]
    return J @ g["cov"][:p, :p] @ np.swapaxes(J, 1, 2)


def first_point(g: dict) -> tuple[float, float]:
    """A draw's (:func:`draw_parts`) orientation error against its prediction at its first
    inside joint vector: ``u = P(|x| <= |e|)`` for ``x`` from the prediction (Satterthwaite's
    chi-square, the bound's own; uniform on 0-1 over draws for a right prediction) and the
    whitened ``e^T S^-1 e`` (chi-square with 3 degrees of freedom, mean 3, for a right ``S``)."""
    S, e = orientation_covariance(g)[0], g["e_rot"][0]
    tr, tr2 = np.trace(S), float(np.sum(S * S.T))
    n2 = float(e @ e)
    return float(chi2.cdf(n2 * tr / tr2, tr**2 / tr2)), float(e @ np.linalg.solve(S, e))


EXACT_SAMPLES = 200_000
"""Samples of a draw's predicted orientation covariance for the exact 95 % quantile of the norm
:func:`bound_check` compares the bound's with (its sampling error about 0.2 %)."""

EXACT_DRAWS = 30
"""At most this many draws (spread evenly over them) get that comparison, at their first joint
vector."""


def bound_check(got: list[dict], seed: int = 0, samples: int = EXACT_SAMPLES) -> dict:
    """The orientation bound's test over the draws ``got`` (:func:`draw_parts`; the ok ones;
    module docstring): ``draws``; ``coverage`` the share of (draw, joint vector) pairs within
    the 95 % bound; ``pit`` (d,) each draw's ``P(|x| <= |e|)`` at its first joint vector with
    ``pit_mean`` and the Kolmogorov-Smirnov p ``pit_ks_p`` against the uniform; ``beyond`` the
    draws with ``pit`` above 0.95, ``beyond_range`` a right bound's central 90 % range of that
    count and ``beyond_p`` the chance of at most ``beyond``; ``whitened`` the mean of the draws' whitened
    error at that point (:func:`first_point`; 3 +- ``sqrt(6 / d)`` for a right prediction); ``ratio`` the pooled realised over
    predicted mean square orientation error (every joint vector) with ``ratio_range`` its
    bootstrap 90 % range over the draws; ``quantile_excess`` the largest and the median
    relative excess of the bound's 95 % quantile over the exact one (``samples`` samples of the
    covariance at the first joint vector of at most :data:`EXACT_DRAWS` draws); seeded by
    ``seed``."""
    ok = [g for g in got if g["status"] == "ok"]
    rng = np.random.default_rng(seed)
    z2 = rng.standard_normal((samples, 3)) ** 2
    exact_of = set(np.linspace(0, len(ok) - 1, min(len(ok), EXACT_DRAWS)).round().astype(int))
    inside, pit, white, sq, tr_mean, excess = [], [], [], [], [], []
    for i, g in enumerate(ok):
        S, e = orientation_covariance(g), g["e_rot"]
        n2 = np.sum(e**2, axis=1)
        inside.append(n2 <= norm_quantile(S) ** 2)
        u, w = first_point(g)
        pit.append(u)
        white.append(w)
        sq.append(n2.mean())
        tr_mean.append(np.trace(S, axis1=1, axis2=2).mean())
        if i in exact_of:
            exact = np.sqrt(np.quantile(z2 @ np.linalg.eigvalsh(S[0]), 0.95))
            excess.append(float(norm_quantile(S[0])) / exact - 1.0)
    d = len(ok)
    pits, sq_a, tr_a, ex = np.array(pit), np.array(sq), np.array(tr_mean), np.array(excess)
    boot = rng.integers(0, d, (4000, d))
    beyond = int(np.sum(pits > 0.95))
    return {
        "draws": d,
        "coverage": float(np.mean(np.concatenate(inside))),
        "pit": pits,
        "pit_mean": float(pits.mean()),
        "pit_ks_p": float(kstest(pits, "uniform").pvalue),
        "whitened": float(np.mean(white)),
        "beyond": beyond,
        "beyond_range": (int(binom.ppf(0.05, d, 0.05)), int(binom.ppf(0.95, d, 0.05))),
        "beyond_p": float(binom.cdf(beyond, d, 0.05)),
        "ratio": float(sq_a.sum() / tr_a.sum()),
        "ratio_range": tuple(
            float(x)
            for x in np.quantile(sq_a[boot].sum(axis=1) / tr_a[boot].sum(axis=1), [0.05, 0.95])
        ),  # fmt: skip
        "quantile_excess": (float(ex.max()), float(np.median(ex))),
    }


def bound_lines(b: dict) -> list[str]:
    """The lines :func:`table` prints of a :func:`bound_check`."""
    lo, hi = b["beyond_range"]
    return [
        f"orientation's 95 % bound (covariance alone, inside): covers {100 * b['coverage']:.1f} % "
        f"of the points; at each draw's first point u = P(|x| <= |e|) has mean "
        f"{b['pit_mean']:.3f} (a right bound's 0.5 +- {np.sqrt(1 / 12 / b['draws']):.3f}), "
        f"Kolmogorov-Smirnov p = {b['pit_ks_p']:.2f} against the uniform, {b['beyond']} draws "
        f"beyond the bound (a right bound's {lo}-{hi}, P(<= {b['beyond']}) = "
        f"{b['beyond_p']:.2f}); whitened e^T S^-1 e there: mean {b['whitened']:.2f} (a right "
        f"prediction's 3 +- {np.sqrt(6 / b['draws']):.2f}); realised / predicted mean square "
        f"{b['ratio']:.2f} (bootstrap "
        f"90 % {b['ratio_range'][0]:.2f}-{b['ratio_range'][1]:.2f}); Satterthwaite's 95 % "
        f"quantile over the exact one: at most {100 * b['quantile_excess'][0]:+.2f} % "
        f"(median {100 * b['quantile_excess'][1]:+.2f} %)",
        "",
    ]


def table(got: list[dict], title: str) -> str:
    """The Markdown tables of the draws ``got`` (:func:`draw_parts`; failed ones counted)."""
    ok = [g for g in got if g["status"] == "ok"]
    if not ok:
        return f"{title}: every draw failed ({got[0]['status'] if got else 'no draws'})"
    names = ok[0]["names"]
    z = np.array([g["error"] / np.sqrt(np.diag(g["cov"])) for g in ok])
    dirs = [directions(g) for g in ok]
    k = len(ok)
    lines = [f"{title}: {k} draws ({len(got) - k} failed); a right covariance's mean z^2 is 1 "
             f"+- {np.sqrt(2 / k):.2f}", "",
             "| orientation direction | share of the predicted variance | largest parameters "
             "(unit loading) | mean z^2 along it |", "|---|---|---|---|"]  # fmt: skip
    for j in range(min(DIRECTIONS, len(dirs[0]["share"]))):
        load = np.mean([np.abs(d["load"][:, j]) for d in dirs], axis=0)
        top = np.argsort(load)[::-1][:3]
        lines.append(f"| {j + 1} | {100 * np.mean([d['share'][j] for d in dirs]):.0f} % | "
                     + ", ".join(f"{names[i]} {load[i]:.2f}" for i in top)
                     + f" | {np.mean([d['z'][j] ** 2 for d in dirs]):.2f} |")  # fmt: skip
    ratio = np.array([d["ratio"] for d in dirs])
    lines += ["", *bound_lines(bound_check(ok)),
              f"realised / predicted mean square orientation error (inside): pooled "
              f"{ratio.mean():.2f}; first-order carriage J dp against the true error: at most "
              f"{max(d['linear'] for d in dirs):.1e} of its RMS", "",
              "| parameter | mean z | mean z^2 |", "|---|---|---|"]  # fmt: skip
    order = np.argsort(np.mean(z**2, axis=0))
    for i in order:
        lines.append(f"| {names[i]} | {z[:, i].mean():+.2f} | {np.mean(z[:, i] ** 2):.2f} |")
    lines.append(f"| all {len(names)} | {z.mean():+.2f} | {np.mean(z**2):.2f} |")
    return "\n".join(lines)


def draw_options(ap: argparse.ArgumentParser, draws: int) -> None:
    """The draws' options ``ap`` gets (this script's and
    :mod:`selfcal.benchmarks.board.accuracy_shared`'s): ``--noise-px``, ``--draws`` (default
    ``draws``), ``--first-seed``, ``--jobs`` and ``--keep``."""
    ap.add_argument("--noise-px", type=float, default=0.2, help="corner noise (px, default 0.2)")
    ap.add_argument("--draws", type=int, default=draws, help=f"draws (default {draws})")
    ap.add_argument("--first-seed", type=int, default=1, help="the first draw's seed (default 1)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--keep", type=Path, metavar="DIR",
                    help="keep each draw in DIR and read it from there when the code checked out "
                         "(a clean commit) drew it")  # fmt: skip


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="er4u-paper", help="the robot (default er4u-paper)")
    draw_options(ap, 20)
    ap.add_argument("--fixed-truth", type=int, metavar="SEED",
                    help="keep the truth and postures of SEED, draw only the pixel noise")  # fmt: skip
    ap.add_argument("--noise-offset", type=int, metavar="N",
                    help="keep each draw's truth, draw its noise with the seed N higher")  # fmt: skip
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the draws (one BLAS thread per process) and print the tables."""
    limit_threads(1)
    a = _arguments(argv)
    seeds = range(a.first_seed, a.first_seed + a.draws)
    if a.fixed_truth is not None and a.noise_offset is not None:
        raise UsageError("--fixed-truth and --noise-offset exclude each other: give one")
    if a.noise_offset is not None:
        items = [(a.robot, a.noise_px, s + a.noise_offset, s, a.keep) for s in seeds]
        truth = f"a new truth each, its noise from the seed {a.noise_offset} higher"
    else:
        items = [(a.robot, a.noise_px, s, a.fixed_truth, a.keep) for s in seeds]
        truth = ("a new truth each" if a.fixed_truth is None
                 else f"the truth of seed {a.fixed_truth}")  # fmt: skip
    code = code_version()
    got = map_jobs(kept_draw, [(*item, code) for item in items], a.jobs)
    print(table(got, f"{a.robot} fits {a.noise_px:g} px, seeds {seeds.start}-{seeds.stop - 1} "
                     f"({truth})"))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
