"""How a model error grows with the distance from the calibration postures, read from held-out
rows (issue #29, docs/tool-accuracy.md): a variogram shared by the routes' model errors.

A misfit the chain cannot express (a joint bending under load, a link of another shape) is a
smooth function of the joints that the fit matched as well as a chain can at the postures it
saw; a held-out row at the distance ``d`` (:func:`selfcal.kinematics.tool_error.posture_distance`,
each joint in units of its range, a revolute joint's at most a turn) from its fold's training
postures shows what is left there.
Its variance per coordinate is modelled as

    m^2(d) = c0 + c1 d^2          (c0 = m0^2 the level, c1 = s^2 the growth, both >= 0)

and each held-out row ``i`` gives an excess ``y_i`` (its squared error less what the estimate's
errors and the noise explain) whose expectation is ``c0 a_i + c1 b_i``: ``a_i`` what a unit
level adds to it, ``b_i`` what a unit growth adds (the tracker route: ``a_i = 3``, ``b_i = 3
d_i^2``; the board route's pixels: :mod:`selfcal.calibration.board.accuracy`). ``(c0, c1)`` is
the weighted least-squares fit (weights: the inverse of each excess's variance without a model
error, ``v_i``), its standard errors scaled up by the residuals' spread when that is larger (a
model error adds its own scatter). The folds *show* the growth when ``c1`` exceeds
:data:`selfcal.calibration.accuracy.Z_MODEL_ERROR` standard errors (one-sided). The growth
counted is ``c1``'s one-sided upper confidence bound (:data:`GROWTH_UPPER_Z` standard errors
above it, clipped at 0), as the board route counts the held parameters' deviation
(:mod:`selfcal.calibration.board.held_prior`): the held-out rows lie close to their training
postures, so ``c1`` is poorly known, and its point estimate, often below 0 where the truth
grows, would make an extrapolation look measured. The bound is capped at what alone explains the
rows' pooled excess (``c1 sum b = sum y``: all of it growing, in proportion to the distance), and
the level is what the pooled excess leaves, ``c0 = max(0, (sum y - c1 sum b) / sum a)``: where
the rows are, the model error still explains their excess. Whether a model error is counted at all is the routes' own test, made
before; this only splits it.

What the folds measure reaches as far as their held-out rows lie (the largest distance, kept by the
route as :attr:`selfcal.calibration.accuracy.ModelError.measured_to`, found or not): beyond it ``c0 + c1 d^2`` would be an extrapolation (a bounded misfit, as a joint's
compliance, stops growing; a quadratic does not), so the prediction holds the model error at its
value there and says it is not measured
(:meth:`selfcal.kinematics.tool_error.ToolErrorModel.unmeasured`, the one place that compares).
Unit-free distances; the excess in any unit (m^2, px^2), ``c0`` in it per unit of ``a``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GROWTH_UPPER_Z", "Variogram", "fit_variogram"]

GROWTH_UPPER_Z = 1.645
"""The growth counted is its estimate plus this many standard errors: its one-sided 95 % upper
confidence bound (module docstring)."""


@dataclass(frozen=True)
class Variogram:
    """A model error's variance against the distance (module docstring).

    Attributes:
        level: ``c0`` (per unit of ``a``; e.g. m^2 per coordinate).
        growth: ``c1`` counted (the same per squared unit-free distance): its upper confidence
            bound.
        estimate: ``c1``'s point estimate (may be negative; nan when not fitted).
        shown: whether the held-out rows showed the growth (``t`` above the threshold).
        t: ``c1``'s estimate over its standard error (nan with fewer than 3 rows or
            distances all alike).
    """

    level: float
    growth: float
    estimate: float
    shown: bool
    t: float

    def at(self, d: np.ndarray | float) -> np.ndarray:
        """The variance ``c0 + c1 d^2`` at the distances ``d``."""
        return self.level + self.growth * np.square(np.asarray(d, dtype=float))

    def carried(self, rows: np.ndarray, d: float) -> float:
        """The factor that carries a variance pooled over held-out rows at the distances
        ``rows`` (k,) (their mean excess) to the distance ``d`` under this variogram's shape:
        ``at(d) / mean(at(rows))`` (1 where the variogram is zero). E.g. the tracker's
        orientation model error, read from the same rows as the position's but pooled: at the
        rows' mean distance the pooled variance overstates it by ``mean(d^2) / mean(d)^2``
        of the growing part (~1.2 for distances spread evenly)."""
        pooled = float(np.mean(self.at(rows))) if np.size(rows) else 0.0
        return float(self.at(d)) / pooled if pooled > 0 else 1.0

    def floor(self, d_ref: float) -> float:
        """The level's share of the variance at ``d_ref``: 1 without growth, 0 without level."""
        total = float(self.at(d_ref))
        return 1.0 if total <= 0 else self.level / total


def fit_variogram(excess: np.ndarray, var: np.ndarray, unit_level: np.ndarray,
                  unit_growth: np.ndarray, distance: np.ndarray, z: float) -> Variogram:  # fmt: skip
    """The :class:`Variogram` of held-out rows (module docstring): their excess ``excess`` (k,),
    its variance without a model error ``var`` (k,) (positive), what a unit level ``unit_level``
    (``a``, k) and a unit growth ``unit_growth`` (``b``, k) add to its expectation, and their
    distances ``distance`` (k,) from their folds' training postures; ``z``: the standard errors
    the growth's estimate must exceed to be shown (the routes pass
    :data:`selfcal.calibration.accuracy.Z_MODEL_ERROR`)."""
    y, v, a, b, d = (np.asarray(x, dtype=float).reshape(-1)
                     for x in (excess, var, unit_level, unit_growth, distance))  # fmt: skip
    pooled = max(float(np.sum(y) / np.sum(a)), 0.0) if d.size and np.sum(a) > 0 else 0.0
    flat = Variogram(pooled, 0.0, float("nan"), False, float("nan"))
    if y.size < 3:
        return flat
    w = 1.0 / np.maximum(v, np.finfo(float).tiny)
    X = np.stack([a, b], axis=1)
    XtWX = X.T @ (w[:, None] * X)
    scale = np.sqrt(np.diag(XtWX))  # the test on unit columns: any unit of the distance
    if np.any(scale <= 0) or np.linalg.cond(XtWX / np.outer(scale, scale)) > 1e12:
        return flat  # the distances all alike: no growth to tell
    cov = np.linalg.inv(XtWX)
    c = cov @ (X.T @ (w * y))
    spread = float(np.sum(w * (y - X @ c) ** 2)) / (y.size - 2)
    se = float(np.sqrt(cov[1, 1] * max(1.0, spread)))
    t = float(c[1] / se) if se > 0 else float("nan")
    growth = max(float(c[1]) + GROWTH_UPPER_Z * se, 0.0)
    total = float(np.sum(y))
    if growth * float(np.sum(b)) > total:  # the bound alone exceeds the rows' excess
        growth = max(total, 0.0) / float(np.sum(b))
    level = max((total - growth * float(np.sum(b))) / float(np.sum(a)), 0.0)
    return Variogram(level, growth, float(c[1]), bool(t > z), t)
