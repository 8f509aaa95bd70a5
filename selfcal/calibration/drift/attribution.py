"""What changed, when new images do not fit a board calibration (issue #29)?

Every candidate is one kind of small change, linearised at the calibration: the camera's free
parameters (intrinsics and lens), the chain's tool on the flange (eye-in-hand the camera's
mount, the hand-eye; eye-to-hand the board's mount), the chain's world (eye-in-hand the board's
pose; eye-to-hand the camera's pose) and each joint's offset alone. Each is fitted to the
whitened residuals of :mod:`selfcal.calibration.drift.images` (generalised least squares in the
check's own metric ``Sigma^-1``): how much each lowers the statistic is the check's directed
test of that change (:func:`candidate_fits`). A candidate explains the change when all the
candidates together fit no significantly better than it alone (nested: ``T_h - T_all`` against
chi-square with the difference of their parameter counts, at ``alpha``) and leave nothing
significant. The cause is named only when the candidates that explain it are of one kind
(several joints' offsets are named together); otherwise "cause not named", with the candidates
that explain it or none (not the check's verdict "cannot tell", which says whether anything
changed).

The directed tests (:attr:`Fits.directed`) are the candidates' drops, except that the chain's
tool and world are each tested as two changes, their translation and their rotation (3
parameters each): a mount that moved without turning (or turned in place) shows in one of the
two, and a chi-square of 3 degrees of freedom finds it with fewer pixels than one of 6 (more
of the 0.2 mm camera shifts of ``python -m selfcal.benchmarks.drift.images`` at 0.2 px, for
two more tests in the Bonferroni count).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.drift.p_value import chi2_sf
from selfcal.calibration.drift.views import ViewJacobians

__all__ = ["Attribution", "Fits", "attribute", "candidate_fits"]


@dataclass(frozen=True)
class Attribution:
    """The candidates (key -> what in words), their p-values after the fit, which explain the
    change, the named ``cause`` (a kind: ``camera``, ``hand-eye``, ``world``, ``joint``) or None
    (cause not named) and the fitted size of each explaining candidate (words)."""

    what: dict[str, str]
    p_values: dict[str, float]
    explaining: tuple[str, ...]
    cause: str | None
    sizes: dict[str, str]

    def line(self) -> str:
        """What changed, in words."""
        if self.cause is not None:
            parts = [f"{self.what[k]} ({self.sizes[k]})" for k in self.explaining]
            return "what changed: " + " or ".join(parts)
        if self.explaining:
            return ("what changed: cause not named (each alone explains it: "
                    + "; ".join(f"{self.what[k]} ({self.sizes[k]})" for k in self.explaining)
                    + ")")  # fmt: skip
        return ("what changed: cause not named (no single change of the camera, the mounts or one "
                "joint's offset explains it)")  # fmt: skip

    def to_json(self) -> dict:
        return {
            "cause": self.cause,
            "line": self.line(),
            "explained_by": [{"change": k, "what": self.what[k], "size": self.sizes[k],
                              "p_value": self.p_values[k]} for k in self.explaining],
            "p_values": dict(self.p_values),
        }  # fmt: skip


def _twist_size(x: np.ndarray) -> str:
    return f"{1e3 * np.linalg.norm(x[:3]):.3f} mm, {np.degrees(np.linalg.norm(x[3:])):.4f} deg"


@dataclass(frozen=True)
class Fits:
    """Every candidate's fit to the whitened residuals: by key what it is in words, ``drop``
    (how much it lowers ``T``), ``rank`` (its parameters the views determine), ``x`` its fitted
    change and ``se`` its standard errors; ``union_left`` and ``union_rank`` the fit of all of them together;
    ``directed`` the directed tests (module docstring): by name how much the fit lowers ``T``
    and the rank, chi-square with that rank under "unchanged"; ``directed_columns`` by the
    same name the test's whitened columns (its fit's design)."""

    what: dict[str, str]
    drop: dict[str, float]
    rank: dict[str, int]
    x: dict[str, np.ndarray]
    se: dict[str, np.ndarray]
    union_left: float
    union_rank: int
    directed: dict[str, tuple[float, int]]
    directed_columns: dict[str, np.ndarray]

    def nested_p(self, key: str, T: float) -> float:
        """``P(chi2_{rank_all - rank_h} >= T_h - T_all)``: do all the candidates together fit
        significantly better than ``key`` alone (``T`` the check's statistic)? 1 when ``key``
        spans them."""
        more = self.union_rank - self.rank[key]
        return float(chi2_sf(T - self.drop[key] - self.union_left, more)) if more > 0 else 1.0

    def best(self, T: float) -> str:
        """The candidate that fits best: the largest :meth:`nested_p`, ties (all 0) broken by
        how much it lowers ``T`` beyond its parameter count."""
        return max(self.what, key=lambda k: (self.nested_p(k, T), self.drop[k] - self.rank[k]))


def candidate_fits(white: Callable[[np.ndarray], np.ndarray], rw: np.ndarray,
                   views: list[ViewJacobians], *, eye_to_hand: bool) -> Fits:  # fmt: skip
    """Fit every candidate (module docstring) alone, and all of them together, to the
    whitened residuals ``rw`` (``white`` the whitening map of the check: ``L^-1``) of
    ``views``."""
    n = views[0].joints.shape[1]
    tool = ("the board's mount on the flange" if eye_to_hand
            else "the camera's mount on the flange (hand-eye)")  # fmt: skip
    world = "the camera's pose (base -> camera)" if eye_to_hand else "the board's pose"
    cands: dict[str, tuple[str, np.ndarray]] = {
        "camera": ("the camera's intrinsics", np.concatenate([v.cam for v in views])),
        "hand-eye": (tool, np.concatenate([v.tool for v in views])),
        "world": (world, np.concatenate([v.world for v in views])),
    }
    for j in range(n):
        cands[f"joint {j + 1}"] = (f"joint {j + 1}'s offset",
                                   np.concatenate([v.joints[:, j : j + 1] for v in views]))  # fmt: skip
    T = float(rw @ rw)
    drop, rank, xs, se = {}, {}, {}, {}
    directed: dict[str, tuple[float, int]] = {}
    columns: dict[str, np.ndarray] = {}
    all_w = white(np.concatenate([G for _, G in cands.values()], axis=1))  # one solve
    at = 0
    for key, (_, G) in cands.items():
        Gw = all_w[:, at : at + G.shape[1]]
        at += G.shape[1]
        x, _, rank[key], _ = np.linalg.lstsq(Gw, rw, rcond=None)
        left = rw - Gw @ x
        drop[key], xs[key] = T - float(left @ left), x
        se[key] = np.sqrt(np.clip(np.diag(np.linalg.pinv(Gw.T @ Gw)), 0.0, None))
        if key in ("hand-eye", "world"):  # a twist: its translation and its rotation apart
            for part, cols in (("translation", slice(0, 3)), ("rotation", slice(3, 6))):
                directed[f"{key} {part}"] = _drop(Gw[:, cols], rw)
                columns[f"{key} {part}"] = Gw[:, cols]
        else:
            directed[key] = (drop[key], int(rank[key]))
            columns[key] = Gw
    x, _, union_rank, _ = np.linalg.lstsq(all_w, rw, rcond=None)
    Gw = all_w
    left = rw - Gw @ x
    return Fits({k: w for k, (w, _) in cands.items()}, drop, rank, xs, se, float(left @ left),
                int(union_rank), directed, columns)  # fmt: skip


def _drop(Gw: np.ndarray, rw: np.ndarray) -> tuple[float, int]:
    """How much the least-squares fit of the whitened columns ``Gw`` lowers ``rw @ rw``, and
    their rank."""
    x, _, rank, _ = np.linalg.lstsq(Gw, rw, rcond=None)
    left = rw - Gw @ x
    return float(rw @ rw - left @ left), int(rank)


def attribute(fits: Fits, T: float, dof: int, views: list[ViewJacobians], *,
              camera_names: tuple[str, ...] = (), alpha: float) -> Attribution:  # fmt: skip
    """Which candidates of ``fits`` explain the change (the check's statistic ``T`` with ``dof``
    degrees of freedom): a candidate explains it when the others together improve its fit by
    no significant amount (``P(chi2_{rank_all - rank_h} >= T_h - T_all) >= alpha``) and all of
    them together leave nothing significant; ``camera_names`` the camera's free parameters'
    names (for the sizes)."""
    names = camera_names or tuple(f"p{i}" for i in range(views[0].cam.shape[1]))
    p_values: dict[str, float] = {}
    sizes: dict[str, str] = {}
    whole = chi2_sf(fits.union_left, dof - fits.union_rank) >= alpha
    for key in fits.what:
        x = fits.x[key]
        p_values[key] = fits.nested_p(key, T)
        if key == "camera":  # the two parameters the fit moves most, in standard errors
            se = fits.se[key]
            top = np.argsort(-np.abs(x) / np.where(se > 0, se, np.inf))[:2]
            sizes[key] = ", ".join(f"{names[i]} {x[i]:+.4g}" for i in top)
        elif key.startswith("joint"):
            sizes[key] = f"{np.degrees(x[0]):+.4f} deg"
        else:
            sizes[key] = _twist_size(x)
    explaining = tuple(k for k, p in p_values.items() if p >= alpha) if whole else ()
    kinds = {k.split(" ")[0] for k in explaining}
    cause = next(iter(kinds)) if len(kinds) == 1 else None
    return Attribution(dict(fits.what), p_values, explaining, cause, sizes)
