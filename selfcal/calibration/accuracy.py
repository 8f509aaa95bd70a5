"""What every route's predicted tool-point accuracy shares (issue #29, docs/tool-accuracy.md).

A route (the tracker's :mod:`selfcal.calibration.tracker.accuracy`, the board's
:mod:`selfcal.calibration.board.accuracy`) predicts the error of its calibrated tool point from
the estimate's covariance carried through the chain
(:class:`selfcal.kinematics.tool_error.ToolErrorModel`) plus a *model error*: what its model
cannot express, estimated from cross-validated rows. Each held-out row ``i`` gives its squared
tool-point error ``|r_i|^2``, what the fold's own covariance explains there (``tr S_i``) and what
the measurement noise explains (``tr N_i``); the model error per coordinate ``m`` follows from

    mean |r_i|^2 = mean tr S_i + mean tr N_i + 3 m^2

counted only when the excess exceeds :data:`Z_MODEL_ERROR` standard errors of the mean
(:func:`excess`). The same for the orientation. (The board route measures its held-out errors in
pixels and splits them there: :mod:`selfcal.calibration.board.accuracy`.) Here: that split (:func:`model_error_of`), its
record (:class:`ModelError`), the ``accuracy`` block of ``calibration.json``
(:class:`Accuracy`) and its reading back (:func:`error_model_from_json`,
:func:`postures_from_json`). SI inside; ``_mm`` / ``_deg`` in the block.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from selfcal.errors import InputError
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices
from selfcal.kinematics.tool_error import Reach, ToolErrorModel, WorkspaceSample, joint_spans

if TYPE_CHECKING:
    from selfcal.calibration.growth import Variogram

__all__ = [
    "SAMPLE_COUNT",
    "Z_MODEL_ERROR",
    "Accuracy",
    "ModelError",
    "error_model_from_json",
    "excess",
    "excess_test",
    "model_error_of",
    "postures_from_json",
    "spans_from_json",
    "spans_json",
    "unmeasured_beyond",
]

SAMPLE_COUNT = 256
"""Joint vectors per region of the workspace sample."""

Z_MODEL_ERROR = 2.0
"""A model error is counted when the held-out errors exceed what the estimation error and the
noise explain by more than this many standard errors (one-sided, ~2 %): an excess of that size
arises by chance in 1 calibration in 40 that has no model error; below it the estimate would
be mostly the sampling noise of the held-out errors, which clipped at 0 inflates the
prediction."""


def excess_test(total2: float, expected2: float, rows: int) -> tuple[float, float]:
    """The held-out test of :func:`excess`: what ``total2`` (the mean squared norm of ``rows``
    held-out 3-vectors) leaves beyond ``expected2`` (what the estimation error and the noise
    explain) in standard errors of ``total2`` under no model error (a squared norm of three
    Gaussian coordinates has variance 2/3 of its square mean; +-inf when that is 0), and the
    smallest per-coordinate model error the test counts, ``sqrt(Z se / 3)`` (the unit of
    ``total2``'s root, e.g. m)."""
    extra, se = total2 - expected2, expected2 * np.sqrt(2.0 / (3.0 * rows))
    z = extra / se if se > 0 else (np.inf if extra > 0 else -np.inf)
    return float(z), float(np.sqrt(Z_MODEL_ERROR * se / 3.0))


def excess(total2: float, expected2: float, rows: int) -> float:
    """Per-coordinate standard deviation of what ``total2`` (the mean squared norm of ``rows``
    held-out 3-vectors) leaves beyond ``expected2`` (what the estimation error and the noise
    explain); 0 unless that excess exceeds :data:`Z_MODEL_ERROR` standard errors of ``total2``
    under no model error (:func:`excess_test`)."""
    if excess_test(total2, expected2, rows)[0] <= Z_MODEL_ERROR:
        return 0.0
    return float(np.sqrt((total2 - expected2) / 3.0))


@dataclass(frozen=True)
class ModelError:
    """The model error estimated from held-out rows (module docstring); SI.

    Attributes:
        position_m, rotation_rad: per-coordinate standard deviations (rotation: None when the
            route does not measure the tool's orientation).
        folds, rows, failed: folds used, rows predicted, folds whose fit failed.
        held_out_rms_m, held_out_rms_rad: RMS of the held-out errors' norms (rad: nan without
            orientation); estimation_rms_m, estimation_rms_rad: what the folds' covariances
            explain (``sqrt(mean tr S)``); noise_m, noise_rad: the measurement noise per
            coordinate taken out (``sqrt(mean tr N / 3)``).
        noise_what: what the noise is (e.g. the tracker's stated sigma).
        reach_distance: when the model error grows with the distance from the calibration
            postures (:class:`selfcal.kinematics.tool_error.ToolErrorModel`), the distance at
            which it is ``position_m``; 0: the same everywhere.
        growth: how the held-out rows' model error grows with their distance
            (:mod:`selfcal.calibration.growth`), or None when not read.
        measured_to: the held-out rows' largest distance from their folds' training postures
            (unit-free, :func:`selfcal.kinematics.tool_error.posture_distance`), whether or not
            they showed a model error: beyond it no fold tested the model, so a model error
            found there or not is not measured (:attr:`limit`); 0: the folds tested it only at
            training postures (everything beyond them not measured); None: not read (no limit).
            The one source of this distance (a :class:`Variogram` read from the same rows does
            not keep it).
        held_rms_m, held_rms_rad: what the deviation from the drawing of the parameters the
            calibration held adds to the held-out errors' norms (``sqrt(mean tr(S_c - S))``,
            ``S_c`` the folds' covariances with the share ``c`` of the deviation the calibration
            counts, :mod:`selfcal.calibration.board.held_prior`): the board route's; None where
            not measured (the tracker route, a file written before it).
        whitened_m, whitened_rad: the held-out rows' tool-pose excess with each row in its own
            metric (:func:`selfcal.calibration.whitened.whitened_excess` of ``e_i`` against ``S_i + N_i``), per coordinate;
            None where not measured (the tracker route, a file written before it).
    """

    position_m: float
    rotation_rad: float | None
    folds: int
    rows: int
    failed: int
    held_out_rms_m: float
    held_out_rms_rad: float
    estimation_rms_m: float
    estimation_rms_rad: float
    noise_m: float
    noise_rad: float
    noise_what: str = "the tracker noise"
    reach_distance: float = 0.0
    growth: Variogram | None = None
    measured_to: float | None = None
    held_rms_m: float | None = None
    held_rms_rad: float | None = None
    whitened_m: float | None = None
    whitened_rad: float | None = None

    @property
    def limit(self) -> float:
        """The distance beyond which the model error is not measured: :attr:`measured_to`
        (0 included: nothing beyond the training postures measured), infinite when not read."""
        return np.inf if self.measured_to is None else float(self.measured_to)

    @property
    def reach_floor(self) -> float:
        """The share (0-1) of the model error's variance at :attr:`reach_distance` that does
        not grow with the distance (1: none of it grows)."""
        if self.growth is None or self.reach_distance <= 0:
            return 0.0
        return self.growth.floor(self.reach_distance)

    def to_json(self) -> dict:
        def num(x: float | None, k: float) -> float | None:
            return None if x is None or not np.isfinite(x) else float(x * k)

        deg = 180.0 / np.pi
        return {
            "what": "per-coordinate standard deviation of what the model cannot express, from "
            "the cross-validated rows' errors less the folds' predicted estimation error and "
            f"{self.noise_what}",
            "position_mm": num(self.position_m, 1e3),
            "rotation_deg": num(self.rotation_rad, deg),
            "folds": self.folds,
            "rows": self.rows,
            "failed_folds": self.failed,
            "held_out_rms_mm": num(self.held_out_rms_m, 1e3),
            "held_out_rms_deg": num(self.held_out_rms_rad, deg),
            "estimation_rms_mm": num(self.estimation_rms_m, 1e3),
            "estimation_rms_deg": num(self.estimation_rms_rad, deg),
            "noise_mm": num(self.noise_m, 1e3),
            "noise_deg": num(self.noise_rad, deg),
            **(
                {}
                if self.held_rms_m is None
                else {
                    "held_deviation_rms_mm": num(self.held_rms_m, 1e3),
                    "held_deviation_rms_deg": num(self.held_rms_rad, deg),
                }
            ),
            **(
                {}
                if self.whitened_m is None
                else {
                    "whitened_excess_mm": num(self.whitened_m, 1e3),
                    "whitened_excess_deg": num(self.whitened_rad, deg),
                    "whitened_what": "per-coordinate size of the held-out tool poses' excess "
                    "with each row weighed by its own estimation and noise covariance (a "
                    "single view's pose is known far worse along its line of sight)",
                }
            ),
            "reach_distance": self.reach_distance or None,
            **(
                {}
                if self.growth is None
                else {
                    "constant_share": self.reach_floor,
                    "growth_shown": self.growth.shown,
                    "growth_t": num(self.growth.t, 1.0),
                    "growth_what": "the model error's variance per coordinate c0 + c1 d^2 at the "
                    "distance d from the calibration postures: c1 counted at its one-sided 95 % upper "
                    "bound from the held-out rows (growth_t: its estimate over its standard error; "
                    "shown above 2)",
                }
            ),
            **(
                {}
                if not np.isfinite(self.limit)
                else {
                    "measured_to_distance": self.limit,
                    "beyond_measured": "beyond the held-out rows' largest distance from the "
                    "calibration postures (measured_to_distance, a fraction of the joints' "
                    "ranges, a revolute joint's at most a turn: joint_spans_si) no fold tested "
                    "the model: model error not measured (found or not), held at its value there",
                }
            ),
        }


def model_error_of(
    r2: Sequence[np.ndarray],
    s2: Sequence[np.ndarray],
    n2: Sequence[np.ndarray],
    rot: tuple[Sequence[np.ndarray], Sequence[np.ndarray], Sequence[np.ndarray]] | None,
    *,
    folds: int,
    failed: int,
    noise_what: str,
    given: tuple[float, float | None] | None = None,
    reach_distance: float = 0.0,
    growth: Variogram | None = None,
    measured_to: float | None = None,
) -> ModelError | None:
    """The :class:`ModelError` of held-out rows given fold by fold: their squared tool-point
    errors ``r2`` (m^2), what the folds' covariances explain ``s2`` (``tr S``, m^2) and what the
    noise explains ``n2`` (``tr N``, m^2), each a list of per-fold arrays; ``rot`` the same
    three for the orientation (rad^2) or None; ``given``: the model error (position m, rotation
    rad) when the route estimated it otherwise (the board route, from the pixels), None for
    :func:`excess` of the squared norms; ``reach_distance``, ``growth``, ``measured_to``:
    :attr:`ModelError.reach_distance`, :attr:`ModelError.growth`, :attr:`ModelError.measured_to`
    (kept whether or not a model error is found).
    None without rows."""
    if not r2 or sum(len(v) for v in r2) == 0:
        return None
    n_rows = int(sum(len(v) for v in r2))
    e2, es2, en2 = (float(np.mean(np.concatenate(v))) for v in (r2, s2, n2))
    out_rot, e2r, es2r, en2r = None, float("nan"), float("nan"), float("nan")
    if rot is not None:
        e2r, es2r, en2r = (float(np.mean(np.concatenate(v))) for v in rot)
        out_rot = excess(e2r, es2r + en2r, n_rows)
    pos = excess(e2, es2 + en2, n_rows)
    if given is not None:
        pos, out_rot = given
    return ModelError(
        position_m=pos,
        rotation_rad=out_rot,
        folds=folds,
        rows=n_rows,
        failed=failed,
        held_out_rms_m=float(np.sqrt(e2)),
        held_out_rms_rad=float(np.sqrt(e2r)),
        estimation_rms_m=float(np.sqrt(es2)),
        estimation_rms_rad=float(np.sqrt(es2r)),
        noise_m=float(np.sqrt(en2 / 3.0)),
        noise_rad=float(np.sqrt(en2r / 3.0)),
        noise_what=noise_what,
        reach_distance=reach_distance if pos > 0 else 0.0,
        growth=growth if pos > 0 else None,
        measured_to=measured_to,
    )


@dataclass(frozen=True)
class Accuracy:
    """The predicted accuracy of a calibration (module docstring): its error model, the
    estimated parameters' ``names``, the model-error estimate, the summary over the workspace
    (:func:`selfcal.kinematics.tool_error.workspace_summary`) of ``sample`` and the calibration
    postures ``q_cal`` (m, n) rad / m; ``what`` says what is predicted in which frame, ``note``
    why there is no model error when ``model_error`` is None, ``extra`` further keys of the
    block (e.g. the board route's cross-validated reprojection)."""

    error_model: ToolErrorModel
    names: tuple[str, ...]
    model_error: ModelError | None
    summary: dict
    sample: WorkspaceSample
    q_cal: np.ndarray
    what: str
    note: str
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The ``accuracy`` block of ``calibration.json`` (units in the key names)."""
        em = self.error_model
        return {
            "what": self.what,
            "units": "mm and deg; covariance SI (rad, m) in the order of `estimated`",
            "model_error": None if self.model_error is None else self.model_error.to_json(),
            "model_error_note": None if self.model_error is not None else self.note,
            "calibrated_region_si": self.sample.box.tolist(),
            "calibration_postures_si": self.q_cal.tolist(),
            "regions": self.summary,
            "estimated": list(self.names),
            "covariance_si": em.covariance.tolist(),
            **self.extra,
        }


def error_model_from_json(
    block: dict,
    model: MCPCModel,
    T_out_world: np.ndarray,
    names: tuple[str, ...],
    poses: bool,
    where: str,
    *,
    fix: str,
    T_tool_point: np.ndarray | None = None,
) -> ToolErrorModel:
    """The :class:`ToolErrorModel` of a calibration file's ``accuracy`` block (``names``: the
    model's minimal parameter names, ``poses``: whether the orientation is predicted, ``fix``:
    how to write the block again, ``T_tool_point``: the tool point in the chain's tool frame);
    the model error grows from the calibration postures when the block says so
    (``model_error.reach_distance``, ``constant_share``, ``joint_limits_si``) and is not measured
    beyond ``model_error.measured_to_distance``, whether or not one was found.

    Raises:
        InputError: the block's parameters are not the file's or its covariance is malformed.
    """
    est = tuple(block.get("estimated", ()))
    unknown = [n for n in est if n not in names]
    cov = np.asarray(block.get("covariance_si", []), dtype=float)
    if unknown or cov.shape != (len(est), len(est)) or not np.all(np.isfinite(cov)):
        raise InputError(f"{where}: the accuracy block's covariance does not match its "
                         f"parameters {list(est)}", fix=fix)  # fmt: skip
    idx = minimal_indices(model.joint_types)
    cols = idx[[names.index(n) for n in est]]
    me = block.get("model_error") or {}
    pos = (me.get("position_mm") or 0.0) / 1e3
    rot = np.radians(me.get("rotation_deg") or 0.0) if poses else None
    tip = None if T_tool_point is None else np.asarray(T_tool_point, float)
    em = ToolErrorModel(model, np.asarray(T_out_world, float), cols, cov, pos, rot, tip)
    reach = float(me.get("reach_distance") or 0.0)
    floor = float(me.get("constant_share") or 0.0)  # an older file: all of it grows
    span = spans_from_json(block, model.n, where, fix=fix)
    limit = unmeasured_beyond(me)
    if span is not None and (reach > 0 or np.isfinite(limit)):  # an older file: none of it
        q_cal = postures_from_json(block, model.n, where, fix=fix)
        em = em.with_reach(Reach(q_cal, span, reach, floor if reach > 0 else 0.0, limit))
    return em


def unmeasured_beyond(model_error: ModelError | dict | None) -> float:
    """The distance from the calibration postures beyond which ``model_error`` (a
    :class:`ModelError` or its ``to_json``) is not measured: the held-out rows' largest
    (:attr:`ModelError.limit`), whether or not they showed a model error; infinite without one
    (an older file: no limit); 0 is a limit (nothing beyond the calibration postures measured)."""
    if isinstance(model_error, ModelError):
        return model_error.limit
    to = (model_error or {}).get("measured_to_distance")
    return np.inf if to is None else float(to)


def spans_json(span: np.ndarray | None) -> dict:
    """The ``accuracy`` block's ``joint_spans_si`` (the unit of its distances, read back by
    :func:`spans_from_json`) of the spans ``span`` (n,) rad / m, or nothing without spans."""
    return {} if span is None else {"joint_spans_si": np.asarray(span, float).tolist()}


def spans_from_json(block: dict, n: int, where: str, *, fix: str) -> np.ndarray | None:
    """The unit (n,) rad / m of an ``accuracy`` block's distances (``reach_distance``,
    ``measured_to_distance``): its ``joint_spans_si`` (:func:`joint_spans`: each joint's range, a
    revolute joint's at most a turn); an older block without it measured them in the limits'
    full ranges (``joint_limits_si``), kept so that its numbers mean what they meant; None
    without either (the model error the same everywhere).

    Raises:
        InputError: ``joint_spans_si`` is not n finite positive values.
    """
    if "joint_spans_si" not in block:
        return (
            None if "joint_limits_si" not in block else joint_spans(block["joint_limits_si"], None)
        )
    span = np.asarray(block["joint_spans_si"], dtype=float)
    if span.shape != (n,) or not np.all(np.isfinite(span) & (span > 0)):
        raise InputError(f"{where}: accuracy.joint_spans_si must be {n} positive joint ranges "
                         "(rad / m)", fix=fix)  # fmt: skip
    return span


def postures_from_json(block: dict, n: int, where: str, *, fix: str) -> np.ndarray:
    """The calibration postures (m, n) rad / m of an ``accuracy`` block.

    Raises:
        InputError: missing or malformed.
    """
    q = np.asarray(block.get("calibration_postures_si", []), dtype=float)
    if q.ndim != 2 or q.shape[1] != n or len(q) == 0 or not np.all(np.isfinite(q)):
        raise InputError(f"{where}: accuracy.calibration_postures_si must be m rows of {n} "
                         "joint values", fix=fix)  # fmt: skip
    return q
