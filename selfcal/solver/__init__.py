"""One sparse nonlinear least-squares engine (Levenberg-Marquardt), vectorised over residual rows.

- :mod:`selfcal.solver.problem`: parameter blocks (held coordinates, instances, bounds) and residual blocks
  (batches of homogeneous rows with Jacobian pieces) laid out as one unknown vector;
- :mod:`selfcal.solver.losses`: robust losses on each row's norm (IRLS);
- :mod:`selfcal.solver.linear`: dense, sparse and Schur-complement normal equations, damped solves;
- :mod:`selfcal.solver.schur`: the Schur form's assembly, its structure built once per solve;
- :mod:`selfcal.solver.lm`: the LM loop, its options, budget and result;
- :mod:`selfcal.solver.covariance`: blocks of ``(J^T J)^-1`` after a solve; a covariance's symmetric
  square root, to draw from it.
"""

from selfcal.solver.covariance import (
    block_columns,
    covariance,
    inverse_block,
    inverse_columns,
    psd_sqrt,
    scaled_rank,
    scaled_rank_of_normal,
    schur_normal_matrix,
    schur_scaled_rank,
)
from selfcal.solver.linear import DENSE_MAX
from selfcal.solver.lm import SolverOptions, SolverResult, cost_and_weights, solve
from selfcal.solver.losses import LOSSES, Loss
from selfcal.solver.problem import Evaluation, JacobianPiece, ParameterBlock, Problem, ResidualBlock
from selfcal.solver.schur import SchurPlans

__all__ = [
    "DENSE_MAX",
    "LOSSES",
    "Evaluation",
    "JacobianPiece",
    "Loss",
    "ParameterBlock",
    "Problem",
    "ResidualBlock",
    "SchurPlans",
    "SolverOptions",
    "SolverResult",
    "block_columns",
    "cost_and_weights",
    "covariance",
    "inverse_block",
    "inverse_columns",
    "psd_sqrt",
    "scaled_rank",
    "scaled_rank_of_normal",
    "schur_normal_matrix",
    "schur_scaled_rank",
    "solve",
]
