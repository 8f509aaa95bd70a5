"""What the arm's deviation from its drawing does to a board calibration's estimate (issue #29).

The parameter selection (:mod:`selfcal.calibration.board.param_selection`) estimates some
kinematic parameters and holds the others at the robot file's values. The arm's minimal
parameters differ from the drawing by ``d``; at the calibration's frames that moves the pixels
by ``D d`` (``D`` (rows, k) the pixels' derivative by every minimal parameter), and the
least-squares fit takes it as data: its estimate moves by ``Y d``, ``Y = (J^T J)^-1 J^T D``
(:func:`held_response`; ``J`` the fit's Jacobian in px, its joint read-back prior included).
The calibrated chain then errs, per unit deviation, by

    R = [M Y_kin - I; Y_camera]

on the minimal parameters (``M`` the estimated parameters' map to them,
:func:`selfcal.calibration.board.bounds.to_minimal`) and the first camera's free parameters
(:func:`held_error`). A deviation along the directions the estimate spans is absorbed exactly
(``R d = 0``: the fit recovers it); what is left is the held directions' part less what the
estimated parameters take of it at the calibration frames, where it is therefore small in the
pixels but not at a workspace point away from them (nor at the tool point, which the camera
does not see). Weighed by the deviation's prior ``S`` it is the covariance ``R S R^T`` the
predicted accuracy and the drift check add (:mod:`selfcal.calibration.board.held_prior`).

Only the first camera's rows are counted (a rig's other cameras see the same deviation: taken
as unseen, like the model error's response in :mod:`selfcal.calibration.board.misfit`); first
order in ``d``. Frames as in :mod:`selfcal.calibration.board.misfit`; SI, px.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from selfcal.errors import UsageError

__all__ = ["held_error", "held_response"]


def held_response(J: sp.spmatrix, Z: np.ndarray, rows: list[np.ndarray],
                  D: list[np.ndarray]) -> np.ndarray:  # fmt: skip
    """``Y`` (len(cols), k) (module docstring): how far the least-squares estimate of the
    Jacobian ``J`` (rows px) moves the unknowns whose columns of ``(J^T J)^-1`` are ``Z`` (n,
    len(cols)) (:func:`selfcal.solver.inverse_columns`) per unit deviation of each of ``k``
    parameters, frame ``i``'s residual rows ``rows[i]`` moved by ``D[i]`` (len(rows[i]), k)."""
    if not rows:
        raise UsageError("no frame to take the deviation's response from")
    JtD = sp.csr_matrix(J)[np.concatenate(rows)].T @ np.concatenate(D)
    return Z.T @ np.asarray(JtD)


def held_error(Y: np.ndarray, M: np.ndarray | None, at: int, n0: int) -> np.ndarray:
    """``R`` (k + n0, k) (module docstring): the error of the minimal parameters (k) and the
    first camera's free ones (n0) per unit deviation of every minimal parameter from the
    drawing, from :func:`held_response`'s ``Y`` (its rows the cameras' ``at`` unknowns, then the
    estimated kinematic ones; its columns the minimal parameters), ``M`` (k, n_kin) the
    estimated parameters' map to the minimal ones (:func:`selfcal.calibration.board.bounds.to_minimal`;
    None: they are the minimal ones)."""
    kin = Y[at:] if M is None else M @ Y[at:]
    k = Y.shape[1]
    if kin.shape[0] != k:
        raise UsageError(f"shapes do not match: Y {Y.shape}, M {None if M is None else M.shape}")
    R = np.zeros((k + n0, k))
    R[:k] = kin - np.eye(k)  # the estimate's response less the deviation itself
    R[k:] = Y[:n0]
    return R
