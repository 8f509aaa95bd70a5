"""The cross-validation folds of the board route's parameter selection
(:mod:`selfcal.calibration.board.param_selection`, step 3): frames whose arm joints -- all but the
wrist's last three, all of a chain of three or fewer -- are equal within
:data:`SAME_CONFIGURATION` form one configuration, and the configurations are the folds, at most
:data:`MAX_FOLDS` of them. The plan's forecast of the selection
(:mod:`selfcal.calibration.board.plan.selection`) and ``selfcal plan --add`` use the same folds.

The order of the frames is irrelevant (issue #29): the frames are grouped in the lexicographic
order of their arm joints (the first joint first) and the configurations numbered in that order,
so the labels, and the folds dealt from them, are a function of each frame's joints and the set
of all frames' joints, never of the rows' order.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "MAX_FOLDS",
    "MIN_COUNTED",
    "MIN_FRAMES",
    "PLACEMENT_FRAMES",
    "SAME_CONFIGURATION",
    "configurations",
    "counted_folds",
    "fold_labels",
    "not_counted_words",
    "unseen",
]

SAME_CONFIGURATION = np.radians(0.1)
"""Arm joints this close (rad; m for a prismatic joint: 0.1 mm) make one configuration."""
MAX_FOLDS = 5
"""Configurations beyond this many are dealt into this many folds (every 5th together)."""
MIN_COUNTED = 2
"""Folds that must count (:func:`counted_folds`) for a cross-validation: the paired rule's
standard error needs two."""
PLACEMENT_FRAMES = 3
"""Frames whose camera poses determine the placement (the camera's mount and the board's pose)
with the nominal chain: two motions about different axes (one motion leaves the mount's
translation along its axis free)."""
MIN_FRAMES = PLACEMENT_FRAMES + 1
"""Fewest frames that show the board for a board calibration (``selfcal calibrate``,
``selfcal plan --count``): with one frame per arm configuration (the most folds) the
selection's folds then each leave out one frame, at most half, so they all count
(:data:`MIN_COUNTED` or more), and each fits the placement on the other
:data:`PLACEMENT_FRAMES`; with fewer no kinematic parameter can be cross-validated. What the
postures identify beyond the placement the rank test says (a 2-joint pan-tilt's 4 frames
calibrate, its selection keeping the fair nominal). It was 6, set by hand."""


def _arm(
    q: np.ndarray, joint_types: tuple[str, ...], whole: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """The arm joints (m, a) of the joints ``q`` (m, n) rad / m (all but the last three when
    there are more than three; every joint when ``whole``) and their tolerance (a,) for one
    configuration."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[1]
    arm = q[:, : n - 3] if n > 3 and not whole else q
    tol = np.array([SAME_CONFIGURATION if t == "revolute" else 1e-4 for t in joint_types])
    return arm, tol[: arm.shape[1]]


def configurations(
    q: np.ndarray, joint_types: tuple[str, ...], *, whole: bool = False
) -> np.ndarray:
    """(m,) the configuration of every frame of the joints ``q`` (m, n) rad / m: taken in the
    lexicographic order of their arm joints (all but the last three when there are more than
    three; the first joint first), a frame whose arm joints are all within
    :data:`SAME_CONFIGURATION` (0.1 deg, 0.1 mm) of a configuration's first frame belongs to it,
    else starts the next. So the configurations are numbered by their joints (the smallest first
    joint first), and a permutation of the rows permutes the labels alike (module docstring).
    ``whole``: every joint counts (the tracker route's rows, whose tool point the wrist moves:
    :mod:`selfcal.calibration.tracker.cross_validation`)."""
    arm, tol = _arm(q, joint_types, whole)
    label = np.empty(len(arm), dtype=int)
    reps: list[np.ndarray] = []
    for i in np.lexsort(arm.T[::-1]):  # stable; rows it ties are equal and so labelled alike
        a = arm[i]
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
    there are more configurations (configuration ``k`` to fold ``k % MAX_FOLDS``: numbered by
    their joints, :func:`configurations`, each fold then holds configurations from the whole
    range of the first joint)."""
    config = np.asarray(config, dtype=int)
    return config % MAX_FOLDS if config.max(initial=-1) + 1 > MAX_FOLDS else config.copy()


def counted_folds(fold_of: np.ndarray) -> np.ndarray:
    """(f,) bool: which folds count in the selection's cross-validation, for the folds
    ``np.unique(fold_of[fold_of >= 0])`` in that order (``fold_of`` (m,) every frame's fold,
    :func:`fold_labels`; -1: a frame in none): a fold counts when the frames it leaves out are
    at most half of the frames in a fold, its training part at least the other half.

    Why (issue #30): a fold stands for the calibration on all the frames by a fit on its training
    part, and its error estimates the prediction error of a fit on that many frames. The larger a
    candidate, the more its error falls with the frames it is fitted to, so a fold trained on few
    frames overstates the larger candidates' error against the smaller ones' (cross-validation's
    bias toward small models where the training part is small); the one-standard-error rule then
    reads that bias as evidence. No K-fold design trains on less than half of the data (two folds
    is the limit), and here a fold leaving out the majority is a dataset of one configuration
    predicted from the few postures added to it (docs/plan.md: the eye-to-hand ``--add 5``
    calibrations, whose fold leaving out 12 of 17 frames was the one the 30 parameters predicted
    worse in 12 of 12 truths, better in 47 of the other 48 folds). The rule is the design's, the
    same for every candidate, so each candidate is still compared with the others on the same
    folds (paired). Not chosen: a fold that "cannot determine" a candidate not counted -- that
    depends on the candidate, so two candidates would be compared on different folds and a
    candidate could gain by the folds it drops; the selection's folds already hold a parameter
    their training part cannot determine (rank or conditioning) at the fair nominal's value.
    With fewer than :data:`MIN_COUNTED` folds counting there is no cross-validation (the
    selection keeps the nominal, as for one configuration)."""
    fold_of = np.asarray(fold_of, dtype=int)
    labels = np.unique(fold_of[fold_of >= 0])
    sizes = np.array([np.sum(fold_of == f) for f in labels])
    return 2 * sizes <= sizes.sum()


def not_counted_words(fold_of: np.ndarray) -> str:
    """The folds :func:`counted_folds` does not count, in words (``""`` when every fold counts):
    e.g. "fold 3 (12 of 17 frames) not counted: it leaves out more than half of the frames"."""
    fold_of = np.asarray(fold_of, dtype=int)
    labels = np.unique(fold_of[fold_of >= 0])
    n = int(np.sum(fold_of >= 0))
    out = [f"fold {k} ({int(np.sum(fold_of == f))} of {n} frames)"
           for k, (f, c) in enumerate(zip(labels, counted_folds(fold_of))) if not c]  # fmt: skip
    if not out:
        return ""
    return (f"{', '.join(out)} not counted: it leaves out more than half of the frames, so its "
            "fit on the rest stands for a smaller experiment than the calibration")  # fmt: skip


def unseen(q: np.ndarray, q_cal: np.ndarray, joint_types: tuple[str, ...]) -> np.ndarray:
    """(m,) bool: the frames of the joints ``q`` (m, n) rad / m whose arm configuration is none
    of the calibration's postures ``q_cal`` (k, n): no posture's arm joints are all within
    :data:`SAME_CONFIGURATION` of theirs (the rule of :func:`configurations`)."""
    arm, tol = _arm(q, joint_types)
    cal, _ = _arm(q_cal, joint_types)
    near = np.all(np.abs(arm[:, None, :] - cal[None, :, :]) <= tol, axis=2)
    return ~np.any(near, axis=1)
