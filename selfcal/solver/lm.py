"""Levenberg-Marquardt over a :class:`~selfcal.solver.problem.Problem`: the one optimiser loop.

Nielsen damping (``lam`` x ``max(1/3, 1 - (2 rho - 1)^3)`` on success, ``lam`` x ``nu``, ``nu`` x 2
on failure), Marquardt scaling (see :mod:`selfcal.solver.linear`), robust losses by IRLS on each
residual row's norm. Stopping rules (``tol`` relative):

1. gradient: ``max |S g| <= 1e-3 tol sqrt(2 cost)`` (``S g`` the Marquardt-scaled gradient);
2. cost/step: an accepted step with ``cost_old - cost_new <= tol cost_old`` or
   ``|dx| <= tol (|x| + tol)``, or ``cost <= 1e-30``; or a trial that does not lower the cost
   though the model predicted a decrease (> 0) below the cost's rounding,
   ``min(tol, COST_ROUNDING) cost_old``: x is the minimum to rounding, where raising the damping
   only shrinks steps that the rounding rejects (x stays);
3. damping saturated: ``lam > 1e16`` after a failure;
0. budget: ``max_iterations`` Jacobian evaluations or ``max_evaluations`` trials.

Bounds (a problem with bounded unknowns, :class:`selfcal.solver.problem.ParameterBlock`; dense
or sparse linear solver): the unknowns at a bound whose descent direction leaves the box are held
for the iteration (their rows and columns of the normal equations decoupled, their gradient
left out of the gradient rule), the others' step is projected onto the box, and the predicted
decrease is that of the projected step (projected Levenberg-Marquardt). A problem without bounds
runs exactly as before.

Every trial counts toward ``max_evaluations``: a residual evaluation, a failed factorisation of
the damped system, a rejected step. NaN/inf at the start, in a Jacobian or in the normal
equations raise :class:`selfcal.errors.SolverError` naming the residual block; a trial point with
NaN/inf residuals is a rejected step, and if the loop ends on such rejections the error names
the block that produced them; if it ends on damped systems that cannot be factored, the
error says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from selfcal.errors import SolverError, UsageError
from selfcal.solver.linear import (
    DENSE_MAX,
    DampedSystem,
    NormalEquations,
    SingularSystem,
    assemble,
)
from selfcal.solver.problem import Evaluation, Problem
from selfcal.solver.schur import SchurAssembler, SchurPlans

__all__ = ["SolverOptions", "SolverResult", "solve", "cost_and_weights", "COST_ROUNDING"]

COST_ROUNDING = 1e-14
"""A decrease of the cost below this fraction of it is within the rounding of its sum over many
rows (about 50 machine epsilons): a rejected trial step that promised no more is the end."""


@dataclass(frozen=True)
class SolverOptions:
    """``tol`` (relative; see the module docstring), budgets, the linear solver ("auto", "dense",
    "sparse", "schur") and for "schur"/"auto" the parameter block whose instances are eliminated
    (``eliminate``; "auto" eliminates it when the problem has more than ``schur_min_unknowns``
    and at most :data:`DENSE_MAX` are kept, else dense LU up to :data:`DENSE_MAX` unknowns and
    SuperLU above. Measured (CPU s of ``calibrate``, analytic default scenario): the Schur form
    is as fast as dense LU at 30 postures and 1.2x faster at 100, and it grows linearly in the
    postures where LU grows cubically)."""

    tol: float = 1e-12
    max_iterations: int = 100
    max_evaluations: int = 10_000
    linear_solver: str = "auto"
    eliminate: str | None = None
    schur_min_unknowns: int = 0
    initial_damping: float = 1e-4


@dataclass(frozen=True)
class SolverResult:
    """Outcome of :func:`solve`. ``x``: unknowns; ``values``: block name -> full flat array;
    ``residuals``: residual block name -> (k, d) at ``x``; ``cost`` ``1/2 sum rho``; ``iterations``
    (Jacobian evaluations), ``nfev`` (residual evaluations incl. the start), ``trials`` (budget
    used); ``status`` 0 budget, 1 gradient, 2 cost/step, 3 damping saturated; ``message``;
    ``damping``: the damping ``lam`` after the loop's last accepted step (the start's when
    none was accepted): a warm start, ``SolverOptions.initial_damping``, for the next solve of
    a nearby problem; a loop that ended on rejected steps (damping saturated, the budget) had
    raised it past any use for that."""

    x: np.ndarray
    values: dict[str, np.ndarray]
    residuals: dict[str, np.ndarray]
    cost: float
    iterations: int
    nfev: int
    trials: int
    status: int
    message: str
    linear_solver: str
    damping: float = SolverOptions.initial_damping

    @property
    def converged(self) -> bool:
        """A tolerance was met or the damping saturated (status > 0)."""
        return self.status > 0


def cost_and_weights(
    problem: Problem, evals: Sequence[Evaluation]
) -> tuple[float, list[np.ndarray]]:
    """Cost ``1/2 sum_blocks sum_rows f^2 rho(|r|^2 / f^2)`` and the IRLS row weights per block."""
    total, weights = 0.0, []
    for blk, ev in zip(problem.residuals, evals):
        r = ev.residuals
        c, w = blk.loss.evaluate(np.sum(r.reshape(len(r), -1) ** 2, axis=1))
        total += float(c.sum())
        weights.append(w)
    return 0.5 * total, weights


def _overflowing(
    problem: Problem, evals: Sequence[Evaluation], weights: Sequence[np.ndarray]
) -> list[str]:
    """Names of the residual blocks whose own normal equations are not finite."""
    params = list(problem.parameters.values())
    return [
        blk.name
        for blk, ev, w in zip(problem.residuals, evals, weights)
        if not assemble(Problem(params, [blk]), [ev], [w], "sparse").is_finite()
    ]


def _blocked(problem: Problem, x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """(n,) the unknowns at a bound whose descent direction ``-g`` leaves the box."""
    return ((x <= problem.lower) & (g > 0)) | ((x >= problem.upper) & (g < 0))


def _held_at_bounds(ne: NormalEquations, held: np.ndarray) -> NormalEquations:
    """``ne`` with the unknowns ``held`` (n,) decoupled (zero gradient, their diagonal alone), so
    the damped step leaves them where they are."""
    if not held.any():
        return ne
    free = (~held).astype(float)
    g = ne.g * free
    if ne.kind == "dense":
        A = ne.dense_A * free[:, None] * free[None, :]
        A[np.diag_indices_from(A)] += np.diag(ne.dense_A) * held
        return NormalEquations("dense", ne.n, g, A=A)
    P = sp.diags(free)
    A_s = (P @ ne.sparse_A @ P + sp.diags(ne.sparse_A.diagonal() * held)).tocsc()
    return NormalEquations("sparse", ne.n, g, A=A_s)


def _linear_kind(problem: Problem, opt: SolverOptions) -> tuple[str, np.ndarray | None]:
    kind = opt.linear_solver
    inst = problem.instance_of_columns(opt.eliminate) if opt.eliminate else None
    if kind == "auto":
        kept = problem.n if inst is None else int(np.sum(inst < 0))
        eliminated = inst is not None and kept < problem.n
        if eliminated and kept <= DENSE_MAX and problem.n > opt.schur_min_unknowns:
            kind = "schur"
        else:
            kind = "dense" if problem.n <= DENSE_MAX else "sparse"
    if kind == "schur" and inst is None:
        raise UsageError("linear_solver='schur' needs eliminate=<parameter block name>")
    if kind == "schur" and problem.bounded:
        raise UsageError("bounded unknowns need the dense or sparse linear solver, not schur")
    return kind, inst


def solve(
    problem: Problem, options: SolverOptions | None = None, plans: SchurPlans | None = None
) -> SolverResult:
    """Minimise the problem's cost from its initial values (see the module docstring).
    ``plans``: the Schur form's structures kept from an earlier solve or check of the same
    structure (:class:`selfcal.solver.schur.SchurPlans`; the Schur form only).

    Raises:
        SolverError: NaN/inf residuals at the start, in a Jacobian or in the normal equations,
            or the loop ended rejecting steps with NaN/inf residuals (the message names the
            residual block and, for a Jacobian, the parameter block) or on damped systems that
            cannot be factored.
        ValueError: an unknown linear solver or loss, or an elimination that does not apply.
    """
    opt = options or SolverOptions()
    kind, inst = _linear_kind(problem, opt)
    schur = SchurAssembler(problem, inst, plans) if kind == "schur" and inst is not None else None
    tol = opt.tol
    x = problem.x0.copy()
    evals = problem.evaluate(x)
    problem.check_finite(evals, "the start")
    cost, _ = cost_and_weights(problem, evals)
    nfev = trials = 1
    it = 0
    lam, nu = opt.initial_damping, 2.0
    lam_accepted = lam  # the damping after the last accepted step (SolverResult.damping)
    status, message = 0, "maximum number of iterations or evaluations reached"
    bad_block: str | None = None  # the block whose NaN/inf rejected the last trial
    singular: str | None = None  # why the last trial's damped system could not be solved
    while it < opt.max_iterations and trials < opt.max_evaluations:
        it += 1
        jev = problem.evaluate(x, jacobian=True)
        _, weights = cost_and_weights(problem, jev)
        ne = assemble(problem, jev, weights, kind, inst, schur)
        if not ne.is_finite():  # a NaN/inf residual or Jacobian entry ends here too: named first
            problem.check_finite(jev, f"iteration {it}")
            raise SolverError(
                f"the normal equations overflow (NaN/inf) at iteration {it} in residual blocks "
                f"{_overflowing(problem, jev, weights)}",
                fix="scale the residuals (e.g. divide by their standard deviation)",
            )
        if problem.bounded:  # a component pushing out of the box at its bound cannot move
            system = DampedSystem(_held_at_bounds(ne, _blocked(problem, x, ne.g)))
        else:
            system = DampedSystem(ne)
        sg = system.scaled_gradient()
        if np.max(np.abs(sg), initial=0.0) <= tol * 1e-3 * max(np.sqrt(2 * cost), 1e-300):
            status, message = 1, "gradient tolerance reached"
            break
        improved = False
        while trials < opt.max_evaluations:
            trials += 1
            try:
                step = -system.solve(lam)
                x_new = x + step
                if problem.bounded:
                    x_new = np.clip(x_new, problem.lower, problem.upper)
                    step = x_new - x
                ev_new = problem.evaluate(x_new)
                nfev += 1
                bad_block = problem.nonfinite_block(ev_new)
            except SingularSystem as exc:
                bad_block, ev_new, singular = None, None, str(exc)
            if ev_new is not None:
                singular = None
            if ev_new is not None and bad_block is None:
                cost_new, _ = cost_and_weights(problem, ev_new)
                predicted = -(ne.g @ step) - 0.5 * ne.quadratic(step)
                rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
                if rho > 0:
                    small_step = np.linalg.norm(step) <= tol * (np.linalg.norm(x) + tol)
                    small_cost = cost - cost_new <= tol * cost
                    x, evals, cost = x_new, ev_new, cost_new
                    lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                    lam_accepted, nu = lam, 2.0
                    improved = True
                    if small_step or small_cost or cost <= 1e-30:
                        status, message = 2, "cost/step tolerance reached"
                    break
                if 0 < predicted <= min(tol, COST_ROUNDING) * cost:
                    # the model promises less than the cost's rounding and the cost did not
                    # fall: x is the minimum to rounding (more damping only shrinks the step)
                    status, message = 2, "cost/step tolerance reached"
                    break
            lam *= nu
            nu *= 2
            if lam > 1e16:
                status, message = 3, "no further decrease possible (damping saturated)"
                break
        del jev, ne, system  # not alive beside the next iteration's (one Jacobian at a time)
        if status or not improved:
            break
    if bad_block is not None and status in (0, 3):
        raise SolverError(
            f"residual block {bad_block!r} gives NaN/inf residuals at every trial step after "
            f"{it} iterations ({trials} trials); the parameters it uses leave their valid range",
            fix="check the data and the initial values (e.g. points behind a camera)",
        )
    if singular is not None and status in (0, 3):
        raise SolverError(
            f"the damped normal equations cannot be solved ({singular}) after {it} iterations "
            f"({trials} trials); residual blocks {[b.name for b in problem.residuals]}",
            fix="hold the parameters the residuals do not determine (gauge) or check the data",
        )
    return SolverResult(
        x=x,
        values=problem.values(x),
        residuals={b.name: ev.residuals for b, ev in zip(problem.residuals, evals)},
        cost=float(cost),
        iterations=it,
        nfev=nfev,
        trials=trials,
        status=status,
        message=message,
        linear_solver=kind,
        damping=float(lam_accepted),
    )
