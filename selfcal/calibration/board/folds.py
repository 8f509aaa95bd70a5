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

__all__ = ["MAX_FOLDS", "SAME_CONFIGURATION", "configurations", "fold_labels", "unseen"]

SAME_CONFIGURATION = np.radians(0.1)
"""Arm joints this close (rad; m for a prismatic joint: 0.1 mm) make one configuration."""
MAX_FOLDS = 5
"""Configurations beyond this many are dealt into this many folds (every 5th together)."""


def _arm(q: np.ndarray, joint_types: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The arm joints (m, a) of the joints ``q`` (m, n) rad / m (all but the last three when
    there are more than three) and their tolerance (a,) for one configuration."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[1]
    arm = q[:, : n - 3] if n > 3 else q
    tol = np.array([SAME_CONFIGURATION if t == "revolute" else 1e-4 for t in joint_types])
    return arm, tol[: arm.shape[1]]


def configurations(q: np.ndarray, joint_types: tuple[str, ...]) -> np.ndarray:
    """(m,) the configuration of every frame of the joints ``q`` (m, n) rad / m: taken in the
    lexicographic order of their arm joints (all but the last three when there are more than
    three; the first joint first), a frame whose arm joints are all within
    :data:`SAME_CONFIGURATION` (0.1 deg, 0.1 mm) of a configuration's first frame belongs to it,
    else starts the next. So the configurations are numbered by their joints (the smallest first
    joint first), and a permutation of the rows permutes the labels alike (module docstring)."""
    arm, tol = _arm(q, joint_types)
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


def unseen(q: np.ndarray, q_cal: np.ndarray, joint_types: tuple[str, ...]) -> np.ndarray:
    """(m,) bool: the frames of the joints ``q`` (m, n) rad / m whose arm configuration is none
    of the calibration's postures ``q_cal`` (k, n): no posture's arm joints are all within
    :data:`SAME_CONFIGURATION` of theirs (the rule of :func:`configurations`)."""
    arm, tol = _arm(q, joint_types)
    cal, _ = _arm(q_cal, joint_types)
    near = np.all(np.abs(arm[:, None, :] - cal[None, :, :]) <= tol, axis=2)
    return ~np.any(near, axis=1)
