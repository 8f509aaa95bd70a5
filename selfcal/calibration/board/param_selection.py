"""Which kinematic parameters the data support: rank, conditioning, then cross-validation.

A board calibration estimates no fixed parameter set. From the placement of the nominal chain
upward, the parameters are offered in a fixed order and kept as the data allow:

1. the pool (:mod:`selfcal.calibration.board.parameter_pool`): the placement, the zero offsets of
   the revolute joints, then the remaining minimal MCPC parameters of the chain in pivoted-QR
   order of the identification Jacobian at the fair nominal (with the measurement terms' rows);
   a parameter the postures cannot determine is held for *rank* or *conditioning*;
2. nested candidates: the nominal (placement and cameras only), + the identifiable joint
   offsets, then + the further parameters in pivoted-QR order in two steps (the first half,
   then all identifiable ones);
3. leave-one-configuration-out cross-validation (the folds of
   :mod:`selfcal.calibration.board.folds`: one configuration of the arm joints a fold, at most
   :data:`selfcal.calibration.board.folds.MAX_FOLDS`): every candidate is fitted without a
   fold's frames (:func:`selfcal.calibration.board.refine.refine_on_board`, the calibration's
   own objective; a parameter the training frames cannot determine by the test of step 1 --
   joint offsets when they show one configuration -- held at the fair nominal's value) and
   predicts them from their joints alone: each fold's RMS (px); the candidate's CV error is
   their geometric mean (every fold weighs the same, one configuration far outside the others
   does not decide alone), beside the RMS of all predictions. Only the folds that count
   (:func:`selfcal.calibration.board.folds.counted_folds`: those leaving out at most half of
   the frames; its docstring says why) enter the CV error and step 4; a fold leaving out the
   majority is fitted and reported but decides nothing, and with fewer than two folds that
   count there is no cross-validation (the nominal is kept);
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

from dataclasses import dataclass, field, replace

import numpy as np

from selfcal.calibration.board.folds import (
    MIN_COUNTED,
    configurations,
    counted_folds,
    fold_labels,
    not_counted_words,
)
from selfcal.calibration.board.parameter_pool import (
    ParameterPool,
    determined,
    offset_name,
    parameter_indices,
    parameter_pool,
)
from selfcal.calibration.board.refine import (
    BoardObservations,
    Refinement,
    predict_px,
    refine_on_board,
)
from selfcal.errors import EstimationError
from selfcal.kinematics.mcpc import MCPCModel, param_names

__all__ = [
    "Candidate",
    "Selection",
    "cv_error",
    "held_selection",
    "nested_candidates",
    "one_se_rule",
    "select_parameters",
]

FOLD_TOL = 1e-6
"""The solver's relative tolerance (cost and step) in a fold's fit: its prediction then agrees
with a fit to 1e-12 within a thousandth of a pixel, in a third of the iterations."""


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
    number of ``configurations`` and ``folds``, the ``rule`` in words; ``counted`` per fold
    whether it counts (:func:`selfcal.calibration.board.folds.counted_folds`; empty without
    folds)."""

    candidates: list[Candidate]
    chosen: int
    identified: tuple[str, ...]
    held: dict[str, str]
    configurations: int
    folds: int
    rule: str
    notes: list[str] = field(default_factory=list)
    fold_of: np.ndarray | None = field(default=None, repr=False)
    """(m,) every frame's cross-validation fold (:func:`selfcal.calibration.board.folds.fold_labels`
    of the frames with the board; -1: a frame without it), None without folds."""
    counted: tuple[bool, ...] = ()

    @property
    def fit(self) -> Refinement:
        fit = self.candidates[self.chosen].fit
        assert fit is not None
        return fit

    def counts(self, fold: int) -> bool:
        """Whether the fold ``fold`` (a label of :attr:`fold_of`) counts: :attr:`counted`, from
        :func:`selfcal.calibration.board.folds.counted_folds` (True when no fold is recorded).
        The accuracy side (the model error, the held share, the held-out RMS,
        :mod:`selfcal.calibration.board.accuracy`) reads the folds that count, as the selection
        does."""
        if self.fold_of is None or not self.counted:
            return True
        labels = np.unique(self.fold_of[self.fold_of >= 0]).tolist()
        return bool(self.counted[labels.index(int(fold))])

    @property
    def folds_counting(self) -> int:
        """How many of the :attr:`folds` count (:meth:`counts`)."""
        return sum(self.counted) if self.counted else self.folds

    def to_json(self) -> dict:
        return {
            "identified": list(self.identified),
            "held": dict(self.held),
            "chosen": self.candidates[self.chosen].label,
            "rule": self.rule,
            "configurations": self.configurations,
            "folds": self.folds,
            **(
                {"folds_counted": [bool(c) for c in self.counted]}
                if self.counted and not all(self.counted)
                else {}
            ),
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
                    folds: np.ndarray, counted: np.ndarray, max_iter: int) -> None:  # fmt: skip
    """Fill ``cand``'s fit and CV error (step 3) over the folds ``counted`` (bool per fold, in
    the order of ``np.unique``; a fold not counted is fitted and its RMS reported, NaN when its
    fit fails, but it does not enter the CV error). Each fold's fit starts from the fit on every
    frame, except for the parameters the fold's training frames cannot determine (the test of
    step 1 on those frames, :func:`selfcal.calibration.board.parameter_pool.determined`, e.g. joint offsets when they hold one
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
    off_names = [offset_name(j) for j in cand.offset_joints.tolist()]
    fold_ms, fold_n = [], []
    for f, counts in zip(np.unique(folds[obs.used]).tolist(), counted.tolist()):
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
            if not counts:  # decides nothing: reported as no prediction
                fold_ms.append(np.nan)
                fold_n.append(0)
                continue
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
    ok = (n > 0) & counted
    cand.cv_rms_px = float(np.sqrt(np.sum(ms[ok] * n[ok]) / np.sum(n[ok])))
    cand.fold_rms_px = tuple(np.sqrt(ms).tolist())
    cand.cv_px = cv_error(cand.fold_rms_px, counted)


def cv_error(fold_rms_px: tuple[float, ...] | np.ndarray,
             counted: np.ndarray | tuple[bool, ...] | None = None) -> float:  # fmt: skip
    """A candidate's CV error (px, step 3): the geometric mean of its folds' RMS ``fold_rms_px``
    (px) over the folds ``counted`` (bool per fold; None: all), a fold without a prediction
    (NaN) skipped; inf when a counted fold's is; NaN when no fold is left."""
    r = np.asarray(fold_rms_px, dtype=float)
    if counted is not None:
        r = r[np.asarray(counted, dtype=bool)]
    r = r[~np.isnan(r)]
    return float(np.exp(np.mean(np.log(r)))) if len(r) else float("nan")


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
    # the frames with the board alone are numbered and dealt (a frame without it, -1, is in no
    # fold): the plan's forecast of the same postures deals the same folds
    config = np.full(len(obs.q), -1)
    config[used] = configurations(obs.q[used], nominal_fit.joint_types)
    n_config = len(np.unique(config[used]))
    folds = np.full(len(obs.q), -1)
    folds[used] = fold_labels(config[used])
    n_folds = len(np.unique(folds[used]))
    counted = counted_folds(folds[used])
    skipped = not_counted_words(folds[used])
    notes = []
    cross = n_folds >= 2 and int(counted.sum()) >= MIN_COUNTED
    if n_folds < 2:
        cands = cands[:1]
        rule = ("no cross-validation: the frames show one configuration of the arm, so no "
                "kinematic parameter can be checked on postures it was not fitted to")  # fmt: skip
        notes.append(f"only the placement was estimated: {rule}")
    elif not cross:
        cands = cands[:1]
        rule = (f"no cross-validation: of {n_folds} folds fewer than {MIN_COUNTED} count "
                f"({skipped}), so no kinematic parameter can be checked on postures it was not "
                "fitted to")  # fmt: skip
        notes.append(f"only the placement was estimated: {rule}")
    for c in cands:
        if not cross:
            try:
                c.fit = refine_on_board(obs, nominal_fit, c.free_idx, c.offset_joints,
                                        max_iter=max_iter)  # fmt: skip
            except (EstimationError, np.linalg.LinAlgError) as exc:
                c.note = f"the estimator failed on every frame ({_why(exc)})"
        else:
            _cross_validate(obs, nominal_fit, c, folds, counted, max_iter)
    if cands[0].fit is None:
        raise EstimationError(
            f"not even the nominal chain could be placed on the board by reprojection "
            f"({cands[0].note})",
            fix="add frames from other arm configurations (move the first joints, not only the "
            "wrist) and calibrate again",
        )
    if cross:
        chosen, best = one_se_rule(cands, counted)
        rule = (f"one-standard-error rule with paired folds over leave-one-configuration-out "
                f"cross-validation ({n_config} configurations, {n_folds} folds): the smallest "
                f"candidate whose mean log error ratio to the best ({cands[best].label}, "
                f"{cands[best].cv_px:.3f} px), fold by fold, is at most its standard error, "
                f"and (but the nominal) below the nominal's"
                + (f"; {skipped}" if skipped else ""))  # fmt: skip
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
                     folds if cross else None,
                     tuple(counted.tolist()) if cross else ())  # fmt: skip


def held_selection(obs: BoardObservations, nominal_fit: MCPCModel, names: tuple[str, ...], *,
                   max_iter: int = 100) -> Selection:  # fmt: skip
    """The model selection held: the kinematic parameters ``names`` (another calibration's
    chosen candidate, in its order; e.g. a bootstrap refit's, :mod:`selfcal.calibration.board.bootstrap`)
    fitted on every frame of ``obs`` from ``nominal_fit`` (the fair nominal's model), with no
    cross-validation. As in a fold's fit (:func:`_cross_validate`), a parameter these frames
    cannot determine (the test of step 1 on them,
    :func:`selfcal.calibration.board.parameter_pool.determined`) is held at the fair nominal's
    value; the outcome's ``held`` names it with the reason, and every parameter not in
    ``names`` as held by the selection given.

    Raises:
        EstimationError: the fit of ``names`` failed (the message says what was tried).
    """
    used = obs.used
    undetermined = determined(nominal_fit, obs.q[used], names, obs.terms)
    free = tuple(nm for nm in names if nm not in undetermined)
    free_idx, offset_joints = parameter_indices(nominal_fit, free)
    cand = Candidate(f"held: {len(names)} parameters given", free, free_idx, offset_joints)
    try:
        cand.fit = refine_on_board(obs, nominal_fit, free_idx, offset_joints, max_iter=max_iter)
    except (EstimationError, np.linalg.LinAlgError) as exc:
        raise EstimationError(
            f"the fit of the {len(names)} parameters given failed ({_why(exc)}; tried: "
            f"Levenberg-Marquardt from the fair nominal, {len(free)} parameters free"
            + (f", {len(undetermined)} held at the fair nominal as these frames cannot "
               f"determine them" if undetermined else "")
            + f", {max_iter} iterations)",
            fix="let the selection run on these frames (no parameters given)",
        ) from exc  # fmt: skip
    pool = parameter_pool(nominal_fit, obs.q[used], obs.terms)
    held = {nm: "not among the parameters given (the selection held)"
            for nm in (*(n for n, _, _ in pool.order), *pool.held) if nm not in names}  # fmt: skip
    held.update(undetermined)
    config = configurations(obs.q[used], nominal_fit.joint_types)
    rule = (f"the selection held: the {len(names)} parameters given, no cross-validation"
            + (f"; {len(undetermined)} of them held at the fair nominal (these frames cannot "
               "determine them)" if undetermined else ""))  # fmt: skip
    return Selection([cand], 0, free, held, len(np.unique(config)), 0, rule)


def _px(v: float) -> str:
    return f"{v:.3f} px" if np.isfinite(v) else "nothing (a fit failed)"


def one_se_rule(cands: list[Candidate],
                counted: np.ndarray | tuple[bool, ...] | None = None) -> tuple[int, int]:  # fmt: skip
    """(chosen, best) by step 4 of the module docstring over the folds ``counted`` (bool per
    fold, :func:`selfcal.calibration.board.folds.counted_folds`; None: all; every candidate's
    ``cv_px`` over the same, :func:`cv_error`); every candidate's ``log_ratio`` (to the
    nominal, ``cands[0]``) and ``log_diff`` (to the best) set."""
    cv = np.array([c.cv_px for c in cands])
    best = int(np.argmin(cv))
    for c in cands:
        if np.isfinite(c.cv_px):
            c.log_ratio = _paired(c, cands[0], counted)
            c.log_diff = _paired(c, cands[best], counted)
    floor = cands[0].cv_px  # never a candidate that does not predict better than the nominal
    chosen = next((i for i, c in enumerate(cands[: best + 1])
                   if np.isfinite(c.cv_px) and (i == 0 or c.cv_px < floor)
                   and c.log_diff[0] <= c.log_diff[1]), best)  # fmt: skip
    return chosen, best


def _paired(c: Candidate, ref: Candidate,
            counted: np.ndarray | tuple[bool, ...] | None) -> tuple[float, float]:  # fmt: skip
    """The mean over the folds ``counted`` (None: all) of ``c``'s log RMS minus ``ref``'s and
    that mean's standard error (0 with one fold); folds without a prediction skipped. The folds
    that do not count are left out before the logs: their fits train on the few frames the
    other folds hold and may be singular (an infinite RMS in both, whose difference is no
    number; ``selfcal plan --add``'s forecast draws met it as a RuntimeWarning)."""
    a, b = np.array(c.fold_rms_px, dtype=float), np.array(ref.fold_rms_px, dtype=float)
    if counted is not None:
        keep = np.asarray(counted, dtype=bool)
        a, b = a[keep], b[keep]
    d = np.log(a) - np.log(b)
    d = d[np.isfinite(d)]
    se = float(np.std(d, ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0
    return (float(np.mean(d)) if len(d) else 0.0, se)
