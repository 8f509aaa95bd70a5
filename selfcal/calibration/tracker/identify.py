"""Kinematic identification from tracker measurements: positions, poses and distances of the tool.

Input: joint readings ``q`` (m, n) rad (m for prismatic joints) with, per row, the measured
position of a tool point (m) and optionally the orientation of a tool frame, in the tracker's
frame; and/or distances (m) between the tool point at two configurations. Output: the MCPC chain
(:mod:`selfcal.kinematics.mcpc`) whose ``V_0`` holds the tracker-to-base transform and whose ``V_n`` holds the
tool point's offset on the flange (and the measured tool frame's orientation, for poses).

Steps:
1. Placement (:mod:`selfcal.estimation.tracker_start`): the nominal chain is placed in the tracker
   frame by a closed-form rigid fit alternated with a linear fit of the tool point on the flange
   (positions), or by the closed-form robot-world hand-eye solution (poses). The
   estimation works in that placed base frame (the *fit frame*): there the base parameters are
   small and far from the MCPC Euler singularity whatever the tracker's axes are. The result
   keeps ``T_meas_fit`` (tracker <- fit frame) and predicts in the tracker frame.
2. Identifiability: the residual blocks' weighted, column-scaled Jacobian of all minimal
   parameters at the start (:mod:`selfcal.estimation.tracker`); parameters are offered base first,
   then the tool point's offset, the internal frames and last the tool orientation
   (:data:`priority_order`), and a parameter is kept when it adds to the span of those kept
   (:func:`selfcal.kinematics.identifiability.select_identifiable`, pivoted QR when that does not reproduce the
   SVD rank). Positions alone cannot see the orientation of the tool frame: three parameters of
   ``V_n`` come out unidentifiable, numerically. Distances alone cannot see the tracker frame.
   A kept parameter whose column adds less than 1e-3 of itself to the span of those before it
   is held for conditioning (:func:`conditioned`, the board route's test).
3. Too few measurements: the count of parameters these kinds of measurement identify on this
   chain (the rank at well-spread random configurations) must be below the number of equations;
   otherwise :class:`TrackerIdentificationError` says how many rows are needed (the one rule:
   :func:`selfcal.calibration.tracker.rows.rows_needed`, which the planner asks too). When the data
   reach that rank their selection is the structural one; only for poorly excited data does the
   selection also run at the well-spread configurations (which parameters the kinds cannot see,
   which these configurations miss).
4. Levenberg-Marquardt of the one solver (:func:`selfcal.solver.solve`) on the identifiable set,
   the rest held at nominal (their Jacobian columns are never formed); standard deviations ``sigma0^2 (J^T J)^-1`` with the a-posteriori
   ``sigma0`` (1 when the stated sigmas are right). A solve that does not converge raises, saying
   the estimator failed; it blames the data's pairing or units only when the placed nominal
   misses them by more than :data:`PAIRING_RMS_MM`.

Units: SI inside; result fields ending in ``_mm`` / ``_deg`` are for reports.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from selfcal.calibration.board.parameter_pool import ColumnSpan
from selfcal.calibration.identify import IdentificationWarning
from selfcal.calibration.tracker.rows import (
    configurations,
    considered_mask,
    dense_jacobian,
    measurement_blocks,
    rows_needed_at,
    scaled_factor,
)
from selfcal.errors import EstimationError, InputError
from selfcal.estimation.tracker import (
    ChainLayout,
    TrackerDistanceBlock,
    TrackerMeasurements,
    initial_placement,
    tracker_terms,
)
from selfcal.estimation.tracker_start import pose_placement
from selfcal.kinematics.alignment import wrap_params
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.identifiability import select_identifiable, still_joints, triangular_factor
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_is_angle, param_names
from selfcal.kinematics.parameter_estimates import ParameterEstimates
from selfcal.solver import ParameterBlock, Problem, SolverOptions, solve
from selfcal.transforms import inv_pose, make_pose

__all__ = [
    "TrackerMeasurements",
    "TrackerResult",
    "TrackerIdentificationError",
    "initial_placement",
    "priority_order",
    "conditioned",
    "identify_tracker",
    "tracker_terms",
]


PAIRING_RMS_MM = 10.0
"""RMS miss (mm) of the nominal chain placed in the tracker frame above which a failed solve is
blamed on the data's pairing or units: an arm within its drawing's tolerance (a millimetre, half
a degree per parameter) misses by a few millimetres at most."""


class TrackerIdentificationError(EstimationError):
    """The tracker data cannot determine the chain (too few rows, no convergence); the message
    says how many rows are needed or what to change."""


# --------------------------------------------------------------------------------------------
# Identifiability
# --------------------------------------------------------------------------------------------


def priority_order(joint_types: tuple[str, ...]) -> np.ndarray:
    """Positions (into the minimal set) in the order they are offered for estimation: ``V_0``,
    the lengths of ``V_n`` (the tool point), ``V_1 .. V_{n-1}``, the angles of ``V_n``."""
    n = len(joint_types)
    idx = minimal_indices(joint_types)
    frame = idx // 6
    group = np.where(frame == 0, 0, np.where(frame == n, np.where(param_is_angle(idx), 3, 1), 2))
    return np.argsort(group, kind="stable")


def conditioned(A: np.ndarray, order: np.ndarray, keep: np.ndarray) -> dict[int, str | None]:
    """The conditioning test of the columns ``keep`` (k,) bool of ``A`` (e.g. those the rank
    test keeps), offered in ``order``: column -> None when kept, else why not. The board
    route's test (:class:`selfcal.calibration.board.parameter_pool.ColumnSpan`): a column whose
    part outside the span of those accepted before is below ``COND_TOL`` (1e-3) would
    multiply its parameter's variance by more than 1e6; it is determined by a lever the noise
    can create (the UR5e's fifth-link lengths, seen only through a start's tool point a few
    hundredths of a millimetre off the last axis)."""
    span = ColumnSpan(A)
    return {int(k): span.offer(int(k)) for k in order if keep[k]}


def _select(
    model: MCPCModel, A: np.ndarray, cons: np.ndarray, rank_rtol: float
) -> tuple[np.ndarray, int, dict[int, str | None]]:
    """Mask (over the minimal set) of the columns of ``A`` (the minimal parameters ``cons``)
    kept by the rank test when they are offered in :func:`priority_order`, the rank of ``A``,
    and the conditioning test of those (:func:`conditioned`; minimal position -> None or why
    it is held)."""
    pos = {k: i for i, k in enumerate(cons)}
    order = np.array([pos[k] for k in priority_order(model.joint_types) if k in pos], int)
    keep, rank, _ = select_identifiable(A, order, rank_rtol)
    mask = np.zeros(minimal_indices(model.joint_types).size, bool)
    mask[cons[keep]] = True
    reasons = conditioned(A, order, keep)
    cond = {int(cons[k]): why for k, why in reasons.items()}
    return mask, rank, cond


def placed_miss_mm(prob: Problem, blocks: list) -> float:
    """RMS (mm) of the position (else distance) residuals at the problem's start: the nominal
    chain placed in the tracker frame with its fitted tool point."""
    ev = prob.evaluate(prob.x0)
    r = ev[0].residuals / np.reshape(blocks[0].w, (len(blocks[0].w), -1))
    if isinstance(blocks[0], TrackerDistanceBlock):
        return float(np.sqrt(np.mean(r**2))) * 1e3
    return float(np.sqrt(np.mean(np.sum(r[:, :3] ** 2, axis=1)))) * 1e3


def no_convergence(
    prob: Problem,
    blocks: list,
    tried: str,
    fix: str,
    error: type[EstimationError] = EstimationError,
) -> EstimationError:
    """The ``error`` of a solve that did not converge (``tried`` says what did not): the
    estimator's failure (with ``fix``), unless the placed nominal misses the data by more than
    :data:`PAIRING_RMS_MM` (then the data's pairing or units are the likely cause, and the
    message shows why)."""
    rms = placed_miss_mm(prob, blocks)
    if rms > PAIRING_RMS_MM:
        return error(
            f"{tried}; the nominal chain placed in the tracker frame misses the measurements "
            f"by {rms:.3g} mm RMS (more than {PAIRING_RMS_MM:g} mm: not an arm within its "
            "drawing's tolerance)",
            fix="check the joint/measurement pairing (one row per rest), the units "
            "(--joint-units, positions in mm) and the robot file",
        )
    return error(
        f"the estimator failed: {tried}; the data look consistent (the placed nominal chain "
        f"misses them by {rms:.3g} mm RMS, within {PAIRING_RMS_MM:g} mm)",
        fix=fix,
    )


def _kinds(meas: TrackerMeasurements) -> tuple[str, ...]:
    on = (("position", meas.m and meas.R is None), ("pose", meas.m and meas.R is not None))
    return tuple(k for k, b in (*on, ("distance", meas.k)) if b)


# --------------------------------------------------------------------------------------------
# Result and driver
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrackerResult(ParameterEstimates):
    """Outcome of :func:`identify_tracker`. SI units unless a name says otherwise.

    Attributes:
        names, values, std, estimated, held_reason, covariance, rank, n_params:
            :class:`~selfcal.kinematics.parameter_estimates.ParameterEstimates` (the rank of the considered
            parameters' Jacobian at the start).
        model: identified chain in the fit frame (tool = the tool point, or the measured tool
            frame for poses).
        T_meas_fit: (4, 4) tracker frame <- fit frame (constant; see the module docstring).
        condition_number: of the column-scaled weighted Jacobian of the estimated set at the
            solution.
        sigma0: a-posteriori standard deviation of unit weight.
        rms_mm: RMS of the position residual norms (mm) of the position / pose rows (nan if none);
        rms_deg: RMS rotation error (deg) of the pose rows (nan if none); rms_distance_mm.
        kinds: the measurement kinds used (``position``, ``pose``, ``distance``).
        iterations, converged, warnings: of the solve; n_rows, n_distances, n_equations.
    """

    model: MCPCModel
    T_meas_fit: np.ndarray
    condition_number: float
    sigma0: float
    rms_mm: float
    rms_deg: float
    rms_distance_mm: float
    kinds: tuple[str, ...]
    iterations: int
    converged: bool
    n_rows: int
    n_distances: int
    n_equations: int
    residuals: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    warnings: tuple[str, ...] = ()

    def predict(self, q: np.ndarray) -> np.ndarray:
        """Tool-point positions (m, 3) in the tracker frame (m) at joints ``q`` (m, n)."""
        T = self.T_meas_fit @ fk_tool(self.model, np.atleast_2d(q))
        return T[:, :3, 3]

    def predict_poses(self, q: np.ndarray) -> np.ndarray:
        """Tool poses ``T_tracker_tool`` (m, 4, 4) at joints ``q`` (m, n)."""
        return self.T_meas_fit @ fk_tool(self.model, np.atleast_2d(q))


NOISE_NOTE_RATIO = 0.5
"""``sigma0`` below which :func:`stated_noise_note` speaks (the stated noise twice the real)."""
NOISE_NOTE_P = 1e-3
"""and the chi-square's lower tail below which that is not chance."""


def stated_noise_note(res: TrackerResult, sigma_mm: float) -> str | None:
    """A note when the fit's residuals show the tracker far better than ``sigma_mm`` (mm per
    coordinate, as given to the fit): ``sigma0`` below :data:`NOISE_NOTE_RATIO` and
    ``sigma0^2 dof`` in the chi-square's lower tail below :data:`NOISE_NOTE_P`; else ``None``.
    `selfcal check` tests new rows against the stated noise, so a stated noise far above the real
    one hides changes (docs/tool-accuracy.md)."""
    from scipy.stats import chi2

    dof = res.n_equations - int(np.count_nonzero(res.estimated))
    if dof <= 0 or not res.sigma0 < NOISE_NOTE_RATIO:
        return None
    p = float(chi2.cdf(res.sigma0**2 * dof, dof))
    if p >= NOISE_NOTE_P:
        return None
    real = sigma_mm * res.sigma0
    deg = " (and --sigma-deg for the poses)" if "pose" in res.kinds else ""
    return (
        f"the fit's residuals are {res.sigma0:.2f} times the stated tracker noise --sigma-mm "
        f"{sigma_mm:g}{deg} (chi-square over {dof} degrees of freedom, p = {p:.1g}: not chance): "
        f"the tracker is nearer {real:.3g} mm per coordinate. The predicted accuracy takes the "
        f"smaller noise, but `selfcal check` tests new rows against the stated one and misses "
        f"changes the real noise would show -- identify again with --sigma-mm {real:.2g}"
    )


def identify_tracker(
    model: MCPCModel,
    meas: TrackerMeasurements,
    *,
    sigma_t_m: float = 1e-4,
    sigma_r_rad: float = 1e-4,
    sigma_d_m: float = 1e-4,
    hold: tuple[str, ...] | list[str] = (),
    rank_rtol: float = 1e-9,
    max_iterations: int = 100,
    tol: float = 1e-8,
) -> TrackerResult:
    """Identify the minimal MCPC parameters from tracker measurements (module docstring).

    Args:
        model: nominal chain (e.g. ``nominal_mcpc(robot)``; its tool is the flange: the tool point
            and the tracker frame are estimated).
        meas: the measurements (:class:`TrackerMeasurements`, SI, tracker frame).
        sigma_t_m, sigma_r_rad, sigma_d_m: standard deviations of a position coordinate, a
            rotation-vector coordinate and a distance (they weight the kinds against each
            other; the std are scaled by the a-posteriori ``sigma0``).
        hold: minimal parameter names held at nominal.
        tol: the solver's relative tolerance on the cost change and the step (scipy's
            ``least_squares`` default ``ftol``/``xtol``): a step that changes the cost by 1e-8
            of itself moves the parameters by ``sqrt(2e-8 cost)`` standard deviations (below
            0.003 at the benchmark's N = 30 to 300); tighter only spends evaluations on rounding
            (held-out predictions equal to 1e-8 mm at 1e-12, docs/tracker.md).

    Raises:
        InputError: malformed measurements or unknown ``hold`` names.
        TrackerIdentificationError: too few measurements (the message says how many are
            needed) or no convergence.
    """
    meas.check(model.n)
    if not np.all(np.isfinite(model.params)):
        raise InputError("the nominal model holds NaN or inf parameters",
                         fix="check the robot file the model comes from")  # fmt: skip
    idx = minimal_indices(model.joint_types)
    names = tuple(param_names(idx))
    considered = considered_mask(model, hold)
    notes: list[str] = []
    sig = (float(sigma_t_m), float(sigma_r_rad), float(sigma_d_m))

    # 1. placement: work in the placed nominal base frame ("fit frame")
    if meas.m:
        if meas.R is not None:  # the closed form of the poses: positions' start fails with few
            B, X = pose_placement(model, meas.q, make_pose(meas.R, meas.xyz))
            s, R_tool = X[:3, 3], X[:3, :3]
        else:
            (B, s), R_tool = initial_placement(model, meas.q, meas.xyz), None
        params = model.params.copy()
        params[-1, 3:] += s  # V_n Trans(s) = Rx Ry Rz Trans(l + s): still in the gauge
        start = model.with_params(params)
        if R_tool is not None:
            start = start.with_tool(make_pose(R_tool, np.zeros(3)))
    else:
        B = np.eye(4)
        start = model
    Binv = inv_pose(B)
    local = TrackerMeasurements(
        q=meas.q,
        xyz=meas.xyz @ Binv[:3, :3].T + Binv[:3, 3],
        R=None if meas.R is None else Binv[:3, :3] @ meas.R,
        q_a=meas.q_a,
        q_b=meas.q_b,
        d=meas.d,
    )

    # 2./3. identifiability and the count of equations
    cons = np.flatnonzero(considered)
    count, A_spread, p_struct = rows_needed_at(start, local, sig, cons, rank_rtol)
    n_eq, need, what = count.equations, count.need, count.what
    if not count.enough:
        raise TrackerIdentificationError(
            f"too few measurements: {n_eq} equations for the {count.rank} parameters that "
            f"{what} identify on this robot; need at least {need} {what} "
            f"(more than {count.rank} equations), better 3 times that",
            fix=f"measure at least {need} well-spread configurations that move every joint",
        )
    mask, rank, cond = _select(start, scaled_factor(start, local, sig, cons), cons, rank_rtol)
    # Data that reach the structural rank keep the structural set: a structural dependency
    # holds at every configuration, so the ordered selection rejects the same columns. Only
    # poorly excited data need the selection at the well-spread configurations to tell the
    # parameters the kinds cannot see from those these configurations miss.
    struct_mask = mask if rank == p_struct else _select(start, A_spread, cons, rank_rtol)[0]
    held_reason = {h: "explicit" for h in hold}
    kinds = _kinds(meas)
    for nm, c, ok in zip(names, considered, struct_mask):
        if c and not ok:
            held_reason[nm] = f"not identifiable from {' and '.join(kinds)} measurements"
    lost = [nm for nm, c, k in zip(names, considered, mask) if c and not k]
    lost = [nm for nm in lost if nm not in held_reason]
    if rank < p_struct:
        text = (
            f"rank {rank} < {p_struct}: {lost} cannot be identified from these configurations "
            f"({still_joints(configurations(meas), start.joint_types)}); held at nominal"
        )
        notes.append(text)
        warnings.warn(text, IdentificationWarning, stacklevel=2)
    for nm in lost:
        held_reason[nm] = "unidentifiable from this data"
    for k, why in cond.items():
        if why is not None:
            held_reason[names[k]] = why
            mask[k] = False

    # 4. estimation
    # the chain's unknowns are the estimated parameters alone (the held ones are constants of
    # the layout, their Jacobian columns never formed)
    est_flat = np.sort(idx[mask])
    coords = np.full(6 * (start.n + 1), -1, np.int64)
    coords[est_flat] = np.arange(est_flat.size)
    layout = ChainLayout(start, "mcpc", coords)
    blocks = measurement_blocks(layout, local, sig)
    prob = Problem([ParameterBlock("mcpc", start.params.reshape(-1)[est_flat])], blocks)
    sol = solve(prob, SolverOptions(tol=tol, max_iterations=max_iterations))
    if not sol.converged:
        raise no_convergence(
            prob, blocks,
            f"Levenberg-Marquardt on {int(mask.sum())} of {len(names)} parameters did not "
            f"converge in {max_iterations} iterations ({sol.message})",
            "hold the least determined parameters (--hold NAME,...) or add well-spread "
            "postures (selfcal plan --measure tracker); please report it with the data",
            TrackerIdentificationError,
        )  # fmt: skip
    fit = layout.chain(sol.values)
    J = dense_jacobian(blocks, sol.values, np.arange(est_flat.size))
    dof = max(J.shape[0] - J.shape[1], 1)
    sigma0 = float(np.sqrt(2.0 * sol.cost / dof))
    col = np.linalg.norm(J, axis=0)
    R = triangular_factor(J / col)  # column-scaled: the condition number and the covariance
    sv = np.linalg.svd(R, compute_uv=False)
    Rinv = np.linalg.inv(R)
    cov_flat = max(sigma0, 1e-300) ** 2 * (Rinv @ Rinv.T) / np.outer(col, col)
    inv_cond = float(sv[-1] / sv[0])
    final = fit.with_params(wrap_params(fit.params))  # LM moved minimal parameters only
    order = np.searchsorted(est_flat, idx[mask])  # minimal order of the estimated ones
    std = np.full(idx.size, np.nan)
    std[mask] = np.sqrt(np.clip(np.diag(cov_flat), 0.0, None))[order]

    rms_mm = rms_deg = rms_d = float("nan")
    res = {b.name: sol.residuals[b.name] / np.reshape(b.w, (len(b.w), -1)) for b in blocks}
    if meas.m:
        r = res[blocks[0].name]
        rms_mm = float(np.sqrt(np.mean(np.sum(r[:, :3] ** 2, axis=1)))) * 1e3
        if meas.R is not None:
            rms_deg = float(np.degrees(np.sqrt(np.mean(np.sum(r[:, 3:] ** 2, axis=1)))))
    if meas.k:
        rms_d = float(np.sqrt(np.mean(res[blocks[-1].name] ** 2))) * 1e3
    return TrackerResult(
        model=final,
        T_meas_fit=B,
        names=names,
        values=final.params.reshape(-1)[idx],
        std=std,
        estimated=mask,
        held_reason=held_reason,
        covariance=cov_flat[np.ix_(order, order)],
        rank=rank,
        n_params=int(considered.sum()),
        condition_number=float(1.0 / inv_cond) if inv_cond > 0 else float("inf"),
        sigma0=sigma0,
        rms_mm=rms_mm,
        rms_deg=rms_deg,
        rms_distance_mm=rms_d,
        kinds=kinds,
        iterations=sol.iterations,
        converged=sol.converged,
        n_rows=meas.m,
        n_distances=meas.k,
        n_equations=n_eq,
        residuals=res,
        warnings=tuple(notes),
    )
