"""One sparse nonlinear least-squares engine (Levenberg-Marquardt), vectorised over residual rows.

- :mod:`calib.solver.problem`: parameter blocks (held coordinates, instances) and residual blocks
  (batches of homogeneous rows with Jacobian pieces) laid out as one unknown vector;
- :mod:`calib.solver.losses`: robust losses on each row's norm (IRLS);
- :mod:`calib.solver.linear`: dense, sparse and Schur-complement normal equations, damped solves;
- :mod:`calib.solver.schur`: the Schur form's assembly, its structure built once per solve;
- :mod:`calib.solver.lm`: the LM loop, its options, budget and result;
- :mod:`calib.solver.covariance`: blocks of ``(J^T J)^-1`` after a solve.
"""

from calib.solver.covariance import covariance, inverse_block, scaled_rank
from calib.solver.linear import DENSE_MAX
from calib.solver.lm import SolverOptions, SolverResult, cost_and_weights, solve
from calib.solver.losses import LOSSES, Loss
from calib.solver.problem import Evaluation, JacobianPiece, ParameterBlock, Problem, ResidualBlock

__all__ = [
    "DENSE_MAX",
    "LOSSES",
    "Evaluation",
    "JacobianPiece",
    "Loss",
    "ParameterBlock",
    "Problem",
    "ResidualBlock",
    "SolverOptions",
    "SolverResult",
    "cost_and_weights",
    "covariance",
    "inverse_block",
    "scaled_rank",
    "solve",
]
