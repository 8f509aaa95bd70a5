"""The world frame of the one-step refinement (:mod:`selfcal.calibration.field.joint_refine`):
which six minimal MCPC parameters it holds at their two-stage values (:func:`choose_gauge`), and
its error kind (:class:`JointRefinementError`).

With an unknown scene the world frame (6 dof) is free; holding the four base parameters of
``V_0`` (``alpha0, beta0, lx0, ly0``) and two of ``V_1`` fixes it. For ``|alpha1| ~ 90 deg`` (the
SCORBOT) a rotation of the world about joint 1's axis moves exactly ``beta1`` and a shift along
that axis exactly ``ly1``, so those two are held; otherwise the two are chosen by pivoted QR of
the gauge directions (:func:`selfcal.estimation.gauge.gauge_directions`) in the complement of what
the base four absorb. The held set is checked to be transversal to the gauge orbit (the 6 x 6
block of the gauge directions is well conditioned).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from selfcal.errors import EstimationError
from selfcal.estimation.gauge import GaugeChoice, gauge_directions
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_is_angle, param_names

__all__ = ["JointRefinementError", "choose_gauge"]

_BASE_HELD = ("alpha0", "beta0", "lx0", "ly0")
_GAUGE_LENGTH_M = 0.3  # angles are compared with lengths as displacements at this radius


class JointRefinementError(EstimationError):
    """The joint refinement cannot give a trustworthy answer (gauge not fixed, no convergence,
    missing scale markers); the message names the cause and the fix."""


def choose_gauge(model: MCPCModel, *, alpha1_tol_deg: float = 10.0) -> GaugeChoice:
    """Choose the six held parameters: ``alpha0, beta0, lx0, ly0`` and two of the rest.

    If ``|alpha1|`` is within ``alpha1_tol_deg`` of 90 deg: ``beta1, ly1``. Otherwise pivoted QR
    on the gauge directions projected onto the complement of what the base four absorb (angles
    scaled by 0.3 m). Raises :class:`JointRefinementError` if the resulting set is not
    transversal to the gauge orbit (condition number > 1e8).
    """
    idx = minimal_indices(model.joint_types)
    names = param_names(idx)
    G = gauge_directions(model)
    scale = np.where(param_is_angle(idx), _GAUGE_LENGTH_M, 1.0)
    Gs = G * scale[:, None]
    Gs[:, 3:] *= _GAUGE_LENGTH_M  # rotations of the world as displacements too
    alpha1 = float(model.params[1, 0])
    base = [names.index(b) for b in _BASE_HELD]
    if abs(abs(np.degrees(alpha1)) - 90.0) <= alpha1_tol_deg:
        extra = [names.index("beta1"), names.index("ly1")]
        method = "alpha1-90"
    else:
        B = Gs[base]  # (4, 6)
        N = scipy.linalg.null_space(B)  # (6, 2) world motions the base four do not see
        rest = [i for i in range(len(names)) if i not in base]
        _, _, piv = scipy.linalg.qr((Gs[rest] @ N).T, pivoting=True)
        extra = [rest[i] for i in piv[:2]]
        method = "pivoted-qr"
    H = Gs[base + extra]
    H = H / np.linalg.norm(H, axis=1, keepdims=True)
    s = np.linalg.svd(H, compute_uv=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if not cond < 1e8:
        raise JointRefinementError(
            f"the held parameters {[names[i] for i in base + extra]} do not fix the world frame "
            f"(gauge block condition number {cond:.3g}); the robot's first two axes are probably "
            "(nearly) parallel -- this gauge choice does not apply"
        )
    return GaugeChoice(tuple(names[i] for i in base + extra), method, cond)
