"""Benchmark: which parameters' predicted covariance the board calibration's errors realise (#29).

The board accuracy Monte Carlo (:mod:`selfcal.benchmarks.board_accuracy`) pools the predicted
95 % bound's coverage of the flange's true error. This script looks inside one of its rows:
per draw (the same draws, :func:`selfcal.benchmarks.board_accuracy_draw.calibrated`) the
calibration's error in every minimal parameter (against the true chain in the board frame, the
calibration's joint offsets: :func:`selfcal.benchmarks.board_accuracy_draw.true_chain`) and in
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

``--fixed-truth SEED``: every draw keeps the truth and postures of ``SEED`` and draws only new
pixel noise (seeds ``--first-seed``...): the spread over the draws is the pixel noise's part
alone, the mean the joint read-back's (the same rounded counts in every draw).

Run: ``uv run python -m selfcal.benchmarks.board_accuracy_parts [--robot er4u-paper]
[--noise-px 0.2] [--draws 20] [--first-seed 1] [--fixed-truth SEED] [--jobs 1]``.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.benchmarks.board_accuracy_draw import (
    calibrated,
    draw_sample,
    scenario,
    simulated,
    true_chain,
)
from selfcal.benchmarks.pool import map_jobs
from selfcal.calibration.board.accuracy import board_error_model_from_json
from selfcal.camera.spec import values_by_name
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import param_is_angle, param_names
from selfcal.threads import limit_threads

__all__ = ["draw_parts", "directions", "main", "table"]

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
    lines += ["", f"realised / predicted mean square orientation error (inside): pooled "
              f"{ratio.mean():.2f}; first-order carriage J dp against the true error: at most "
              f"{max(d['linear'] for d in dirs):.1e} of its RMS", "",
              "| parameter | mean z | mean z^2 |", "|---|---|---|"]  # fmt: skip
    order = np.argsort(np.mean(z**2, axis=0))
    for i in order:
        lines.append(f"| {names[i]} | {z[:, i].mean():+.2f} | {np.mean(z[:, i] ** 2):.2f} |")
    lines.append(f"| all {len(names)} | {z.mean():+.2f} | {np.mean(z**2):.2f} |")
    return "\n".join(lines)


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="er4u-paper", help="the robot (default er4u-paper)")
    ap.add_argument("--noise-px", type=float, default=0.2, help="corner noise (px, default 0.2)")
    ap.add_argument("--draws", type=int, default=20, help="draws (default 20)")
    ap.add_argument("--first-seed", type=int, default=1, help="the first draw's seed (default 1)")
    ap.add_argument("--fixed-truth", type=int, metavar="SEED",
                    help="keep the truth and postures of SEED, draw only the pixel noise")  # fmt: skip
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the draws (one BLAS thread per process) and print the tables."""
    limit_threads(1)
    a = _arguments(argv)
    seeds = range(a.first_seed, a.first_seed + a.draws)
    got = map_jobs(draw_parts, [(a.robot, a.noise_px, s, a.fixed_truth) for s in seeds], a.jobs)
    truth = "a new truth each" if a.fixed_truth is None else f"the truth of seed {a.fixed_truth}"
    print(table(got, f"{a.robot} fits {a.noise_px:g} px, seeds {seeds.start}-{seeds.stop - 1} "
                     f"({truth})"))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
