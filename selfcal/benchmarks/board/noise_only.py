"""Benchmark: one truth, new noise only -- the board calibration's predicted covariance against
the empirical one of its estimates (#29, the orientation's over-coverage).

The board accuracy Monte Carlo (:mod:`selfcal.benchmarks.board.accuracy`) draws a new truth,
new postures and new noise in every draw and pools coverage. This script holds ONE truth and
ONE set of postures (those of ``--seed``, the Monte Carlo's draw of that seed) and redraws only
what a calibration's predicted covariance is about: the corner noise (``--draws`` noise seeds
from ``--first-noise-seed``) and the joint read-back error. The read-back stays the rounding of
every motor's count (:class:`DitheredReadBack`) but with the count grid shifted by a new
uniform fraction of a count in every draw, so its error has the rounding's distribution and is
new in every draw (with the plain rounding a fixed truth and postures read back the same counts
in every draw: ``--read-back fixed`` keeps that, its spread is then the pixel noise's alone).

At a few joint vectors of each region (the first :data:`POINTS` of the draw's workspace sample,
:func:`selfcal.benchmarks.board.accuracy_draw.draw_sample`, the same in every draw) it compares
the empirical covariance ``S`` (about the draws' mean, ``K - 1`` degrees of freedom) of the true
tool errors (position m, orientation rad as rotation vectors, board frame) with the mean over
the draws of the covariance each calibration predicts there, ``P`` (``J C J^T`` from the
accuracy block's ``covariance_si``, before the model-error term; and with it): along each
principal direction ``v`` of ``P`` (position and orientation apart) the ratio ``v^T S v / v^T P
v``. A right covariance gives ratios whose ``(K - 1)`` multiple is chi-square with ``K - 1``
degrees of freedom: the script prints that 90 % range. The same for the parameters: the
empirical covariance of the calibration's errors in its minimal and camera parameters against
the predicted one (``covariance_si`` with the camera's block and cross block), along the
directions that carry the orientation's predicted variance
(:func:`selfcal.benchmarks.board.accuracy_parts.directions`) and per parameter. Also the
bounds' corner noise (``bounds.pixel_sigma_px``, the fit's own, dof-corrected) against the
simulated one, and in how many draws a model error was counted.

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.board.noise_only --robot ur5e --seed 1
--noise-px 0.2 --draws 100``.
"""

from __future__ import annotations

import argparse
import dataclasses
import pickle
import sys
from pathlib import Path

import numpy as np
from scipy import stats
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.board.accuracy_draw import (
    REGIONS,
    calibrated,
    draw_sample,
    scenario,
    simulated,
    true_chain,
)
from selfcal.benchmarks.board.accuracy_parts import directions
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.accuracy import board_error_model_from_json
from selfcal.camera.spec import values_by_name
from selfcal.io.atomic import write_bytes_atomic
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import param_is_angle, param_names
from selfcal.kinematics.tool_error import norm_quantile
from selfcal.robot.encoder import EncoderSpec, joint_counts, motor_counts
from selfcal.threads import limit_threads

__all__ = ["DitheredReadBack", "POINTS", "noise_draw", "ratios", "report", "main"]

POINTS = 3
"""Joint vectors per region at which the covariances are compared."""


@dataclasses.dataclass(frozen=True, eq=False)
class DitheredReadBack(EncoderSpec):
    """The controller's read-back with every motor's count grid shifted by ``shift`` (n,)
    counts (a uniform fraction in [-0.5, 0.5) drawn per draw): the rounding's error, uniform in
    a count, new in every draw for the same posture. The calibration still reads the robot
    file's table (the same standard deviation, :attr:`EncoderSpec.read_back_sigma`)."""

    shift: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))

    def read_back(self, q: np.ndarray) -> np.ndarray:
        """``q`` (rad / m) as the shifted count grid reads it back (class docstring)."""
        q = np.asarray(q, dtype=float)
        motor = motor_counts((q - self.zero) * self.counts_per_unit, self.differential)
        read = joint_counts(np.rint(motor + self.shift) - self.shift, self.differential)
        return self.zero + read / self.counts_per_unit


def noise_draw(robot: str, sigma_px: float, seed: int, noise_seed: int, q: dict | None,
               read_back: str = "dithered") -> dict:  # fmt: skip
    """One calibration of the truth and postures of ``seed`` with the corner noise (``sigma_px``
    px) and, ``read_back`` ``"dithered"``, the read-back's grid shift of ``noise_seed``. ``q``:
    the regions' joint vectors (rad; None: this draw's first :data:`POINTS` of each). Returns
    ``q``, per region ``err`` (m, 6) the true errors [position m; orientation rad] and ``P``
    (m, 6, 6) the predicted covariance before the model-error term, ``me`` (m, 6) the
    model-error term's variances; ``names``, ``dp`` the parameter errors (minimal then camera;
    rad, m, the camera's units), ``C`` their predicted covariance, ``Jrot`` (m, 3, p) the
    inside points' orientation rows; ``sigma_px`` the bounds' corner noise."""
    s = scenario(robot, sigma_px, seed, noise_seed=noise_seed)
    setup = simulated(s, "fits")
    enc = setup.robot.encoder
    if read_back == "dithered" and enc is not None:
        shift = np.random.default_rng([noise_seed, 7]).uniform(-0.5, 0.5, enc.zero.shape)
        fields = {f.name: getattr(enc, f.name) for f in dataclasses.fields(EncoderSpec)}
        robot_def = dataclasses.replace(
            setup.robot, encoder=DitheredReadBack(**fields, shift=shift)
        )
        setup = dataclasses.replace(setup, robot=robot_def)
    cal, truth, _ = calibrated(s, setup)
    block, bounds = cal.accuracy, cal.bounds
    assert block is not None and bounds is not None
    em = board_error_model_from_json(block, cal.model, "calibration.json")
    if q is None:
        sample = draw_sample(cal, seed)
        q = {r: getattr(sample, r)[:POINTS] for r in REGIONS}
    true_b = true_chain(cal, truth)
    tip = np.asarray(block["T_tool_point_si"])
    out: dict = {"q": q, "sigma_px": float(bounds.pixel_sigma_px),
                 "model_error": bool(em.model_error_m > 0)}  # fmt: skip
    for r in REGIONS:
        T_est, T_true = fk_tool(cal.model, q[r]) @ tip, fk_tool(true_b, q[r]) @ tip
        rot = Rotation.from_matrix(T_est[:, :3, :3] @ np.swapaxes(T_true[:, :3, :3], 1, 2))
        out[r] = {"err": np.c_[T_est[:, :3, 3] - T_true[:, :3, 3], rot.as_rotvec()],
                  "P": em.estimation_covariance(q[r]),
                  "me": em.model_error_factor(q[r])[:, None]
                  * np.r_[[em.model_error_m**2] * 3, [(em.model_error_rad or 0.0) ** 2] * 3]}  # fmt: skip
    dp = (cal.model.params - true_b.params).reshape(-1)[em.columns]
    dp = np.where(param_is_angle(em.columns), (dp + np.pi) % (2 * np.pi) - np.pi, dp)
    cam = cal.cameras[0]
    est, true = values_by_name(cam), values_by_name(setup.intrinsics)
    cross = np.asarray(block["camera_cross_si"])
    out |= {"names": [*param_names(em.columns), *cam.free],
            "dp": np.r_[dp, [est[n] - true[n] for n in cam.free]],
            "C": np.block([[em.covariance, cross], [cross.T, np.asarray(block["camera_covariance_si"])]]),
            "Jrot": em.jacobian(q["inside"])[:, 3:]}  # fmt: skip
    return out


def ratios(E: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The empirical covariance of the errors ``E`` (K, d) about their mean against the
    predicted ``P`` (d, d) along ``P``'s principal directions: (d,) ``v^T S v / lambda``
    (largest predicted variance first) and (d,) the predicted variances ``lambda``."""
    lam, V = np.linalg.eigh(P)
    lam, V = lam[::-1], V[:, ::-1]
    S = np.cov(E, rowvar=False)
    return np.einsum("id,ij,jd->d", V, S, V) / lam, lam


def _chi2_range(k: int) -> str:
    lo, hi = stats.chi2.ppf([0.05, 0.95], k - 1) / (k - 1)
    return f"{lo:.2f}-{hi:.2f}"


def report(got: list[dict], title: str, sigma_px: float) -> str:
    """The Markdown tables of the draws ``got`` (:func:`noise_draw`)."""
    k = len(got)
    lines = [f"{title}: {k} draws; a right covariance's ratio lies in {_chi2_range(k)} (90 %, "
             f"chi-square with {k - 1} degrees of freedom, one direction)", "",
             f"bounds' corner noise: mean {np.mean([g['sigma_px'] for g in got]):.4f} px "
             f"(simulated {sigma_px:g}); a model error counted in "
             f"{sum(g['model_error'] for g in got)} of {k} draws", "",
             "| region | point | part | predicted std along its directions (mm / mdeg) | "
             "empirical / predicted variance along them | with the model-error term | "
             "mean error / predicted std along them |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in REGIONS:
        for i in range(len(got[0][r]["err"])):
            E = np.array([g[r]["err"][i] for g in got])
            P = np.mean([g[r]["P"][i] for g in got], axis=0)
            me = np.mean([g[r]["me"][i] for g in got], axis=0)
            for part, sl, unit in (("position", slice(0, 3), 1e3), ("orientation", slice(3, 6),
                                                                     np.degrees(1.0) * 1e3)):  # fmt: skip
                rat, lam = ratios(E[:, sl], P[sl, sl])
                rat_me, _ = ratios(E[:, sl], P[sl, sl] + np.diag(me[sl]))
                lam_all, V = np.linalg.eigh(P[sl, sl])
                bias = (V[:, ::-1].T @ E[:, sl].mean(axis=0)) / np.sqrt(lam)
                lines.append(f"| {r} | {i + 1} | {part} | "
                             + " / ".join(f"{unit * np.sqrt(x):.3g}" for x in lam) + " | "
                             + " / ".join(f"{x:.2f}" for x in rat) + " | "
                             + " / ".join(f"{x:.2f}" for x in rat_me) + " | "
                             + " / ".join(f"{x:+.2f}" for x in bias) + " |")  # fmt: skip
    lines += ["", *_coverage_table(got), "", *_parameter_table(got)]
    return "\n".join(lines)


def _parameter_table(got: list[dict]) -> list[str]:
    """The parameters' empirical against predicted covariance (module docstring)."""
    names = got[0]["names"]
    D = np.array([g["dp"] for g in got])
    C = np.mean([g["C"] for g in got], axis=0)
    J = got[0]["Jrot"]
    p = J.shape[2]
    dirs = [directions({"J": J, "e_rot": np.einsum("mij,j->mi", J, g["dp"][:p]), "cov": C,
                        "error": g["dp"]}) for g in got]  # fmt: skip
    Z = np.array([d["z"] for d in dirs])  # (K, r) the errors along the directions, in their stds
    d0 = dirs[0]
    lines = ["| orientation direction (parameters) | share of the predicted orientation variance "
             "| largest parameters (unit loading) | empirical / predicted variance | mean / "
             "predicted std |", "|---|---|---|---|---|"]  # fmt: skip
    for j in range(min(3, Z.shape[1])):
        top = np.argsort(np.abs(d0["load"][:, j]))[::-1][:3]
        lines.append(f"| {j + 1} | {100 * d0['share'][j]:.0f} % | "
                     + ", ".join(f"{names[i]} {abs(d0['load'][i, j]):.2f}" for i in top)
                     + f" | {np.var(Z[:, j], ddof=1):.2f} | {Z[:, j].mean():+.2f} |")  # fmt: skip
    lines += ["", "| parameter | predicted std (rad, m, camera units) | empirical / predicted "
              "variance | mean / predicted std |", "|---|---|---|---|"]  # fmt: skip
    std = np.sqrt(np.diag(C))
    var = np.var(D, axis=0, ddof=1)
    for i in np.argsort(var / std**2):
        lines.append(f"| {names[i]} | {std[i]:.3g} | {var[i] / std[i] ** 2:.2f} | "
                     f"{D[:, i].mean() / std[i]:+.2f} |")  # fmt: skip
    return lines


def _coverage_table(got: list[dict]) -> list[str]:
    """Per region and part: how often each draw's own predicted 95 % bound (with the
    model-error term) covers its true error, and the mean of ``e^T P^-1 e / 3`` of the draws'
    errors ``e`` against their own prediction ``P`` (1 for a right one; the errors' mean, the
    fixed truth's own part, included)."""
    lines = ["| region | part | coverage of the 95 % bound | mean e^T P^-1 e / 3 |",
             "|---|---|---|---|"]  # fmt: skip
    for r in REGIONS:
        for part, sl in (("position", slice(0, 3)), ("orientation", slice(3, 6))):
            E = np.concatenate([g[r]["err"][:, sl] for g in got])
            P = np.concatenate([g[r]["P"][:, sl, sl] + np.apply_along_axis(np.diag, 1,
                                                                           g[r]["me"][:, sl])
                                for g in got])  # fmt: skip
            inside = np.linalg.norm(E, axis=1) <= norm_quantile(P)
            m2 = np.einsum("ki,ki->k", E, np.linalg.solve(P, E[..., None])[..., 0]) / 3
            lines.append(f"| {r} | {part} | {100 * inside.mean():.1f} % | {m2.mean():.2f} |")
    return lines


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="ur5e", help="the robot (default ur5e)")
    ap.add_argument(
        "--seed", type=int, default=1, help="the truth's and postures' seed (default 1)"
    )
    ap.add_argument("--noise-px", type=float, default=0.2, help="corner noise (px, default 0.2)")
    ap.add_argument("--draws", type=int, default=100, help="noise draws (default 100)")
    ap.add_argument("--first-noise-seed", type=int, default=1001,
                    help="the first draw's noise seed (default 1001)")  # fmt: skip
    ap.add_argument("--read-back", choices=("dithered", "fixed"), default="dithered",
                    help="a new read-back error per draw (default) or the truth's own rounding")  # fmt: skip
    ap.add_argument("--save", metavar="FILE", help="also pickle the draws to FILE (to reread)")
    ap.add_argument("--load", metavar="FILE", nargs="+",
                    help="print the tables of draws pickled by --save instead of running")  # fmt: skip
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the draws in this process (one BLAS thread) and print the tables."""
    limit_threads(1)
    a = _arguments(argv)
    if a.load:
        loaded = [g for f in a.load for g in pickle.loads(Path(f).read_bytes())]
        print(report(loaded, f"{a.robot} fits {a.noise_px:g} px, draws of {', '.join(a.load)}",
                     a.noise_px))  # fmt: skip
        return 0
    got: list[dict] = []
    q = None
    for n in range(a.first_noise_seed, a.first_noise_seed + a.draws):
        try:
            g = noise_draw(a.robot, a.noise_px, a.seed, n, q, a.read_back)
        except Exception as exc:  # noqa: BLE001 - a benchmark counts failed draws
            print(f"noise seed {n} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
            continue
        q = g["q"]
        got.append(g)
        if a.save:
            write_bytes_atomic(a.save, pickle.dumps(got))
        print(f"draw {len(got)} (noise seed {n}) done", file=sys.stderr, flush=True)
    print(report(got, f"{a.robot} fits {a.noise_px:g} px, the truth and postures of seed "
                      f"{a.seed}, noise seeds {a.first_noise_seed}-"
                      f"{a.first_noise_seed + a.draws - 1}, read-back {a.read_back}", a.noise_px))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
