"""Which kinematic parameters the data support: rank, conditioning, then cross-validation.

A board calibration estimates no fixed parameter set. From the placement of the nominal chain
upward, the parameters are offered in a fixed order and kept as the data allow:

1. the pool, in order: the placement (``V_0``: the board pose, ``V_n``: the hand-eye; always
   estimated, :func:`selfcal.calibration.board.nominal_fit.placement_indices`), the zero offsets of the revolute
   joints, then the remaining minimal MCPC parameters of the chain (``V_1 .. V_{n-1}``) in the
   order of a pivoted QR factorisation of the identification Jacobian (the tool-pose Jacobian of
   :func:`selfcal.kinematics.forward.identification_jacobian` at the fair nominal, rows weighted as
   :func:`selfcal.kinematics.identifiability.analyse_identifiability`'s, columns scaled to unit norm);
   measurement terms (:mod:`selfcal.calibration.board.terms`) add their rows, what they tell
   of the chain beyond their own unknowns
   (:func:`selfcal.calibration.board.terms.identification_rows`);
   a parameter whose column adds nothing to the span of those before it is held for *rank*
   (its orthogonal part below :data:`RANK_TOL`), one that adds too little for *conditioning*
   (below :data:`COND_TOL`: its variance would grow by more than ``1 / COND_TOL**2``);
2. nested candidates: the nominal (placement and cameras only), + the identifiable joint
   offsets, then + the further parameters in pivoted-QR order in two steps (the first half,
   then all identifiable ones);
3. leave-one-configuration-out cross-validation (:func:`configurations`: frames whose arm
   joints -- all but the wrist's last three, all of a chain of three or fewer -- are equal
   within :data:`SAME_CONFIGURATION` form one configuration, at most :data:`MAX_FOLDS` folds):
   every candidate is fitted without a fold's frames (:func:`selfcal.calibration.board.refine.refine_on_board`,
   the calibration's own objective; a parameter the training frames cannot determine by the
   test of step 1 -- joint offsets when they show one configuration -- held at the fair
   nominal's value) and predicts them from their joints alone: each fold's RMS
   (px); the candidate's CV error is their geometric mean (every fold weighs the same, one
   configuration far outside the others does not decide alone), beside the RMS of all
   predictions;
4. the one-standard-error rule with paired folds: the best candidate has the lowest CV error;
   every candidate's log error minus the best's, fold by fold, averaged over the folds, with the
   standard error of that mean from the folds' spread of the difference; the smallest candidate
   whose mean difference is at most its standard error is chosen, and never one (but the
   nominal) whose CV error is not below the nominal's. A larger set is taken only when it
   predicts clearly better in the folds alike, however much the folds differ from each other
   (paired with the nominal, the standard error was the arm's deviation varying by fold: on a
   7-joint arm it hid a ~10 % better prediction of the full set in every fold). The mean log
   ratio to the nominal and its standard error are reported beside.

The chosen candidate's fit on every frame is the calibration. Nothing here reads truth.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.calibration.board.refine import (
    BoardObservations,
    Refinement,
    predict_px,
    refine_on_board,
)
from selfcal.calibration.board.terms import identification_rows
from selfcal.errors import EstimationError
from selfcal.estimation.kinematic_poses import joint_twists
from selfcal.kinematics.forward import identification_jacobian
from selfcal.kinematics.identifiability import pose_sigmas, triangular_factor
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_names
from selfcal.terms.base import Term

__all__ = [
    "COND_TOL",
    "MAX_FOLDS",
    "RANK_TOL",
    "SAME_CONFIGURATION",
    "Candidate",
    "ParameterPool",
    "Selection",
    "ColumnSpan",
    "configurations",
    "determined",
    "determined_each",
    "fold_labels",
    "nested_candidates",
    "one_se_rule",
    "parameter_pool",
    "select_parameters",
]

RANK_TOL = 1e-8
"""Orthogonal part (of a unit column) at or below which a parameter is not identifiable."""
COND_TOL = 1e-3
"""Orthogonal part below which a parameter is held for conditioning (variance x 1e6)."""
SAME_CONFIGURATION = np.radians(0.1)
"""Arm joints this close (rad; m for a prismatic joint: 0.1 mm) make one configuration."""
MAX_FOLDS = 5
"""Configurations beyond this many are dealt into this many folds (every 5th together)."""
FOLD_TOL = 1e-6
"""The solver's relative tolerance (cost and step) in a fold's fit: its prediction then agrees
with a fit to 1e-12 within a thousandth of a pixel, in a third of the iterations."""


def configurations(q: np.ndarray, joint_types: tuple[str, ...]) -> np.ndarray:
    """(m,) the configuration of every frame of the joints ``q`` (m, n) rad / m: frames whose
    arm joints (all but the last three when there are more than three) are all within
    :data:`SAME_CONFIGURATION` (0.1 deg, 0.1 mm) of a configuration's first frame belong to it;
    numbered in order of appearance."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[1]
    arm = q[:, : n - 3] if n > 3 else q
    tol = np.array([SAME_CONFIGURATION if t == "revolute" else 1e-4 for t in joint_types])
    tol = tol[: arm.shape[1]]
    reps: list[np.ndarray] = []
    label = np.empty(len(q), dtype=int)
    for i, a in enumerate(arm):
        for k, r in enumerate(reps):
            if np.all(np.abs(a - r) <= tol):
                label[i] = k
                break
        else:
            label[i] = len(reps)
            reps.append(a)
    return label


def fold_labels(config: np.ndarray) -> np.ndarray:
    """(m,) the fold of every frame: its configuration, dealt into :data:`MAX_FOLDS` folds when
    there are more configurations (configuration ``k`` to fold ``k % MAX_FOLDS``: each fold then
    holds configurations from the whole recording)."""
    config = np.asarray(config, dtype=int)
    return config % MAX_FOLDS if config.max(initial=-1) + 1 > MAX_FOLDS else config.copy()


@dataclass(frozen=True)
class ParameterPool:
    """The parameters offered (:func:`parameter_pool`): ``order`` the accepted ones as
    ``(name, kind, index)`` (``kind`` ``"mcpc"``: a flat MCPC index; ``"offset"``: a joint, 0
    based) in the order offered; ``n_placement``, ``n_offsets`` how many of them are the
    placement and the joint offsets; ``held`` the others by name with the reason."""

    order: tuple[tuple[str, str, int], ...]
    n_placement: int
    n_offsets: int
    held: dict[str, str]


def _offset_name(j: int) -> str:
    return f"offset_j{j + 1}"


class ColumnSpan:
    """The rank and conditioning test of step 1 over the columns of ``R`` (the triangular
    factor of the scaled identification Jacobian): :meth:`offer` accepts a column when its part
    outside the span of those accepted before is large enough, else gives the reason."""

    def __init__(self, R: np.ndarray):
        self.R = R
        self.basis = np.zeros((R.shape[0], 0))

    def orth(self, k: int) -> np.ndarray:
        c = self.R[:, k] / max(float(np.linalg.norm(self.R[:, k])), 1e-300)
        for _ in range(2):  # re-orthogonalise once for stability
            c = c - self.basis @ (self.basis.T @ c)
        return c

    def offer(self, k: int, c: np.ndarray | None = None) -> str | None:
        """None when column ``k`` (its orthogonal part ``c``) is accepted, else why not."""
        c = self.orth(k) if c is None else c
        s = float(np.linalg.norm(c))
        if s <= RANK_TOL:
            return "rank: not identifiable from these postures (a combination of the others)"
        if s < COND_TOL:
            return (f"conditioning: adds {s:.1e} of its column to the others' span "
                    f"(limit {COND_TOL:g})")  # fmt: skip
        self.basis = np.column_stack([self.basis, c / s])
        return None


def _columns(model: MCPCModel, q: np.ndarray, terms: Sequence[Term] = ()
             ) -> tuple[list[str], list[str], list[int], np.ndarray]:  # fmt: skip
    """Every parameter offered (names, kinds, indices: placement, joint offsets, the inner
    minimal parameters) and the triangular factor of their scaled identification Jacobian at
    ``model`` and the joints ``q`` (m, n) rad (step 1 of the module docstring), with the rows
    of the measurement ``terms`` (what they tell of the chain beyond their own unknowns,
    :func:`selfcal.calibration.board.terms.identification_rows`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = model.n
    place = placement_indices(n)
    inner = np.array([k for k in minimal_indices(model.joint_types) if 0 < k // 6 < n], int)
    revolute = [j for j, t in enumerate(model.joint_types) if t == "revolute"]
    J = identification_jacobian(model, q)
    cols = [J[:, :, place], joint_twists(model, q)[:, :, revolute], J[:, :, inner]]
    A = np.concatenate(cols, axis=2) / pose_sigmas(1e-4, 1e-3, len(q))[:, :, None]
    A = A.reshape(-1, A.shape[2])
    if terms:  # their columns [placement, inner, offsets] in the order of A's
        T = identification_rows(terms, model, np.r_[place, inner], np.array(revolute, int))
        order = np.r_[np.arange(len(place)), len(place) + len(inner) + np.arange(len(revolute)),
                      len(place) + np.arange(len(inner))]  # fmt: skip
        A = np.concatenate([A, T[:, order]])
    norm = np.linalg.norm(A, axis=0)
    R = triangular_factor(A / np.where(norm > 0, norm, 1.0))
    names = ([*param_names(place)] + [_offset_name(j) for j in revolute]
             + [*param_names(inner)])  # fmt: skip
    kinds = ["mcpc"] * len(place) + ["offset"] * len(revolute) + ["mcpc"] * len(inner)
    index = [*place.tolist(), *revolute, *inner.tolist()]
    return names, kinds, index, R


def parameter_pool(model: MCPCModel, q: np.ndarray, terms: Sequence[Term] = ()) -> ParameterPool:
    """The pool of step 1 (module docstring) at ``model`` (world = board frame, tool = camera)
    and the joints ``q`` (m, n) rad of the frames used, with the rows of the measurement
    ``terms``."""
    names, kinds, index, R = _columns(model, q, terms)
    n_place = len(placement_indices(model.n))
    n_rev = kinds.count("offset")
    groups = [range(n_place), range(n_place, n_place + n_rev)]
    rest = list(range(n_place + n_rev, len(names)))
    span = ColumnSpan(R)
    order: list[tuple[str, str, int]] = []
    held: dict[str, str] = {}
    counts = []

    def offer(k: int, c: np.ndarray | None = None) -> bool:
        why = span.offer(k, c)
        if why is not None:
            held[names[k]] = why
            return False
        order.append((names[k], kinds[k], index[k]))
        return True

    for g in groups:
        counts.append(sum(offer(k) for k in g))
    while rest:  # pivoted QR: the column with the largest part outside the span next
        parts = [span.orth(k) for k in rest]
        best = int(np.argmax([np.linalg.norm(p) for p in parts]))
        k = rest.pop(best)
        if not offer(k, parts[best]):
            for r in rest:  # every further one adds less still
                offer(r)
            break
    return ParameterPool(tuple(order), counts[0], counts[1], held)


def determined(model: MCPCModel, q: np.ndarray, names: tuple[str, ...],
               terms: Sequence[Term] = ()) -> dict[str, str]:  # fmt: skip
    """Which of the parameters ``names`` (a candidate's, in its order) the joints ``q`` (m, n)
    rad and the measurement ``terms`` cannot determine, by the rank and conditioning test of
    step 1 offered in that order at ``model``: name -> reason (empty when they determine
    all)."""
    return determined_each(model, q, [names], terms)[0]


def determined_each(model: MCPCModel, q: np.ndarray, names: Sequence[tuple[str, ...]],
                    terms: Sequence[Term] = ()) -> list[dict[str, str]]:  # fmt: skip
    """:func:`determined` of every parameter tuple in ``names`` (e.g. each nested candidate's)
    at the same joints ``q``, from one identification Jacobian."""
    all_names, _, _, R = _columns(model, q, terms)
    at = {nm: k for k, nm in enumerate(all_names)}
    out = []
    for group in names:
        span = ColumnSpan(R)
        out.append({nm: why for nm in group if (why := span.offer(at[nm])) is not None})
    return out


@dataclass
class Candidate:
    """One nested candidate: its ``label``, the kinematic parameters it estimates (``names``,
    by kind ``free_idx`` and ``offset_joints``), its fit on every frame (``fit``, None when it
    failed), its CV error ``cv_px`` (the folds' geometric mean, px; inf when a fit failed), the
    RMS of all its predictions ``cv_rms_px``, every fold's RMS ``fold_rms_px``, its mean log
    ratio to the nominal and that mean's standard error ``log_ratio``, the same paired with the
    best candidate's folds ``log_diff`` (step 4 of the module docstring), a ``note`` (why it
    failed) and ``fold_held``: per fold the parameters its training frames cannot determine
    (held at the fair nominal's value in that fold's fit); ``fold_fits``: per fold its fit on
    the other folds' frames with the flat MCPC indices and joint offsets it estimated (the
    predicted accuracy's cross-validation, :mod:`selfcal.calibration.board.accuracy`)."""

    label: str
    names: tuple[str, ...]
    free_idx: np.ndarray
    offset_joints: np.ndarray
    fit: Refinement | None = None
    cv_px: float = float("inf")
    cv_rms_px: float = float("inf")
    fold_rms_px: tuple[float, ...] = ()
    log_ratio: tuple[float, float] = (float("nan"), float("nan"))
    log_diff: tuple[float, float] = (float("nan"), float("nan"))
    note: str = ""
    fold_held: dict[int, tuple[str, ...]] = field(default_factory=dict)
    fold_fits: dict[int, tuple[Refinement, np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False
    )

    def to_json(self) -> dict:
        return {
            "label": self.label,
            "parameters": list(self.names),
            "n_parameters": len(self.names),
            "fit_rms_px": None if self.fit is None else self.fit.rms_px,
            "cv_px": _num(self.cv_px),
            "cv_rms_px": _num(self.cv_rms_px),
            "fold_rms_px": [_num(v) for v in self.fold_rms_px],
            "log_ratio_to_nominal": {
                "mean": _num(self.log_ratio[0]),
                "se": _num(self.log_ratio[1]),
            },
            "log_ratio_to_best": {
                "mean": _num(self.log_diff[0]),
                "se": _num(self.log_diff[1]),
            },
            **({"note": self.note} if self.note else {}),
            **(
                {"held_in_folds": {str(f): list(v) for f, v in self.fold_held.items()}}
                if self.fold_held
                else {}
            ),  # fmt: skip
        }


def _num(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


@dataclass
class Selection:
    """The outcome of :func:`select_parameters`: the ``candidates`` with their CV errors, the
    ``chosen`` one's index, the parameters ``identified`` and ``held`` (name -> reason), the
    number of ``configurations`` and ``folds``, the ``rule`` in words."""

    candidates: list[Candidate]
    chosen: int
    identified: tuple[str, ...]
    held: dict[str, str]
    configurations: int
    folds: int
    rule: str
    notes: list[str] = field(default_factory=list)
    fold_of: np.ndarray | None = field(default=None, repr=False)
    """(m,) every frame's cross-validation fold (:func:`fold_labels`), None without folds."""

    @property
    def fit(self) -> Refinement:
        fit = self.candidates[self.chosen].fit
        assert fit is not None
        return fit

    def to_json(self) -> dict:
        return {
            "identified": list(self.identified),
            "held": dict(self.held),
            "chosen": self.candidates[self.chosen].label,
            "rule": self.rule,
            "configurations": self.configurations,
            "folds": self.folds,
            "candidates": [c.to_json() for c in self.candidates],
        }


def nested_candidates(pool: ParameterPool) -> list[Candidate]:
    """The nested candidates of step 2 (module docstring)."""
    p, o = pool.n_placement, pool.n_offsets
    rest = len(pool.order) - p - o
    ends = [(p, "nominal (placement + camera)")]
    if o:
        ends.append((p + o, "+ joint offsets"))
    steps = sorted({round(rest * f) for f in (1 / 2, 1.0)} - {0})
    for s in steps:
        ends.append((p + o + s, "+ all identifiable" if s == rest else f"+ {s} by pivoted QR"))
    out = []
    for end, label in ends:
        sel = pool.order[:end]
        out.append(Candidate(
            label, tuple(n for n, _, _ in sel),
            np.array([i for _, k, i in sel if k == "mcpc"], dtype=np.int64),
            np.array([i for _, k, i in sel if k == "offset"], dtype=np.int64),
        ))  # fmt: skip
    return out


def _cross_validate(obs: BoardObservations, start: MCPCModel, cand: Candidate,
                    folds: np.ndarray, max_iter: int) -> None:  # fmt: skip
    """Fill ``cand``'s fit and CV error (step 3). Each fold's fit starts from the fit on every
    frame, except for the parameters the fold's training frames cannot determine (the test of
    step 1 on those frames, :func:`determined`, e.g. joint offsets when they hold one
    configuration): those are held at the fair nominal's value (``start``) -- not at the fit
    on every frame's, which has seen the fold."""
    try:
        cand.fit = refine_on_board(obs, start, cand.free_idx, cand.offset_joints,
                                   max_iter=max_iter)  # fmt: skip
    except (EstimationError, np.linalg.LinAlgError) as exc:
        cand.note = (f"the estimator failed on every frame ({_why(exc)}; tried: "
                     f"Levenberg-Marquardt from the fair nominal, {len(cand.names)} parameters "
                     f"free, {max_iter} iterations)")  # fmt: skip
        return
    full = cand.fit
    mcpc_names = param_names(cand.free_idx)
    off_names = [_offset_name(j) for j in cand.offset_joints.tolist()]
    fold_ms, fold_n = [], []
    for f in np.unique(folds[obs.used]).tolist():
        out = folds == f
        held = determined(start, obs.q[obs.used & ~out], cand.names, obs.terms)
        keep_m = np.array([nm not in held for nm in mcpc_names], bool)
        keep_o = np.array([nm not in held for nm in off_names], bool)
        params = full.model.params.reshape(-1).copy()
        params[cand.free_idx[~keep_m]] = start.params.reshape(-1)[cand.free_idx[~keep_m]]
        offsets = np.asarray(full.model.joint_offsets, dtype=float).copy()
        back = cand.offset_joints[~keep_o]
        offsets[back] = np.asarray(start.joint_offsets, dtype=float)[back]
        begin = replace(full.model, params=params.reshape(full.model.params.shape),
                        joint_offsets=offsets)  # fmt: skip
        if held:
            cand.fold_held[int(f)] = tuple(held)
        try:
            fit = refine_on_board(obs, begin, cand.free_idx[keep_m], cand.offset_joints[keep_o],
                                  train=~out, cameras=full.cameras, stds=False,
                                  max_iter=max_iter, tol=FOLD_TOL)  # fmt: skip
        except (EstimationError, np.linalg.LinAlgError) as exc:
            cand.note = (
                f"the estimator failed on fold {f} ({_why(exc)}; tried: Levenberg-Marquardt "
                f"from the fit on every frame on the other folds' frames, "
                f"{int(keep_m.sum() + keep_o.sum())} parameters free"
                + (f", {len(held)} held at the fair nominal as those frames cannot determine "
                   f"them ({', '.join(held)})" if held else "")
                + f", {max_iter} iterations)"
            )  # fmt: skip
            return
        cand.fold_fits[int(f)] = (fit, cand.free_idx[keep_m], cand.offset_joints[keep_o])
        e = predict_px(obs, fit, out)
        fold_ms.append(float(np.mean(np.sum(e**2, axis=1))) if len(e) else np.nan)
        fold_n.append(len(e))
    ms, n = np.array(fold_ms), np.array(fold_n)
    ok = n > 0
    cand.cv_rms_px = float(np.sqrt(np.sum(ms[ok] * n[ok]) / np.sum(n[ok])))
    cand.fold_rms_px = tuple(np.sqrt(ms).tolist())
    cand.cv_px = float(np.exp(np.mean(np.log(np.sqrt(ms[ok])))))


def _why(exc: Exception) -> str:
    """The error's message without its fix: a failed estimator is no finding about the data."""
    return exc.message if isinstance(exc, EstimationError) else f"{type(exc).__name__}: {exc}"


def select_parameters(obs: BoardObservations, nominal_fit: MCPCModel, *,
                      max_iter: int = 100) -> Selection:  # fmt: skip
    """Choose and fit the kinematic parameters the data support (module docstring), starting
    every candidate from ``nominal_fit`` (the fair nominal's model: the placed nominal chain).

    Raises:
        EstimationError: not even the nominal candidate could be fitted on every frame.
    """
    used = obs.used
    pool = parameter_pool(nominal_fit, obs.q[used], obs.terms)
    cands = nested_candidates(pool)
    config = configurations(obs.q, nominal_fit.joint_types)
    n_config = len(np.unique(config[used]))
    folds = fold_labels(config)
    n_folds = len(np.unique(folds[used]))
    notes = []
    if n_folds < 2:
        cands = cands[:1]
        rule = ("no cross-validation: the frames show one configuration of the arm, so no "
                "kinematic parameter can be checked on postures it was not fitted to")  # fmt: skip
        notes.append(f"only the placement was estimated: {rule}")
    for c in cands:
        if n_folds < 2:
            try:
                c.fit = refine_on_board(obs, nominal_fit, c.free_idx, c.offset_joints,
                                        max_iter=max_iter)  # fmt: skip
            except (EstimationError, np.linalg.LinAlgError) as exc:
                c.note = f"the estimator failed on every frame ({_why(exc)})"
        else:
            _cross_validate(obs, nominal_fit, c, folds, max_iter)
    if cands[0].fit is None:
        raise EstimationError(
            f"not even the nominal chain could be placed on the board by reprojection "
            f"({cands[0].note})",
            fix="add frames from other arm configurations (move the first joints, not only the "
            "wrist) and calibrate again",
        )
    if n_folds >= 2:
        chosen, best = one_se_rule(cands)
        rule = (f"one-standard-error rule with paired folds over leave-one-configuration-out "
                f"cross-validation ({n_config} configurations, {n_folds} folds): the smallest "
                f"candidate whose mean log error ratio to the best ({cands[best].label}, "
                f"{cands[best].cv_px:.3f} px), fold by fold, is at most its standard error, "
                f"and (but the nominal) below the nominal's")  # fmt: skip
    else:
        chosen = 0
    held = dict(pool.held)
    chosen_names = set(cands[chosen].names)
    for c in cands[chosen + 1 :]:
        for name in c.names:
            if name not in chosen_names and name not in held:
                held[name] = (f"cross-validation: {c.label} predicts {_px(c.cv_px)} against "
                              f"{_px(cands[chosen].cv_px)} of the chosen "
                              f"{cands[chosen].label}: not clearly better")  # fmt: skip
    return Selection(cands, chosen, cands[chosen].names, held, n_config, n_folds, rule, notes,
                     folds if n_folds >= 2 else None)  # fmt: skip


def _px(v: float) -> str:
    return f"{v:.3f} px" if np.isfinite(v) else "nothing (a fit failed)"


def one_se_rule(cands: list[Candidate]) -> tuple[int, int]:
    """(chosen, best) by step 4 of the module docstring; every candidate's ``log_ratio`` (to the
    nominal, ``cands[0]``) and ``log_diff`` (to the best) set."""
    cv = np.array([c.cv_px for c in cands])
    best = int(np.argmin(cv))
    for c in cands:
        if np.isfinite(c.cv_px):
            c.log_ratio = _paired(c, cands[0])
            c.log_diff = _paired(c, cands[best])
    floor = cands[0].cv_px  # never a candidate that does not predict better than the nominal
    chosen = next((i for i, c in enumerate(cands[: best + 1])
                   if np.isfinite(c.cv_px) and (i == 0 or c.cv_px < floor)
                   and c.log_diff[0] <= c.log_diff[1]), best)  # fmt: skip
    return chosen, best


def _paired(c: Candidate, ref: Candidate) -> tuple[float, float]:
    """The mean over the folds of ``c``'s log RMS minus ``ref``'s and that mean's standard
    error (0 with one fold); folds without a prediction skipped."""
    d = np.log(np.array(c.fold_rms_px)) - np.log(np.array(ref.fold_rms_px))
    d = d[np.isfinite(d)]
    se = float(np.std(d, ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0
    return (float(np.mean(d)) if len(d) else 0.0, se)
