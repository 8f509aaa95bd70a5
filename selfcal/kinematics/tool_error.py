"""Predicted tool-point error of a calibrated chain over the workspace (issue #29).

A calibration's tool pose at joints ``q`` is ``T_out_tool(q) = T_out_world fk(model, q)``. Its
error against the robot's true pose has two parts, both treated as zero-mean Gaussian:

- the *estimation* error: the covariance ``C`` (p, p) of the estimated minimal parameters carried
  through the chain to first order, ``S(q) = J(q) C J(q)^T`` with ``J`` the identification
  Jacobian (:func:`selfcal.kinematics.forward.identification_jacobian`) of the estimated columns,
  rotated into the output frame (rows: position m, orientation rad as a rotation vector);
- the *model* error: what the model cannot express (compliance, a wrong link, a tracker's
  systematic error), a per-coordinate standard deviation estimated from held-out residuals by the
  calibration route (e.g. :mod:`selfcal.calibration.tracker.accuracy`), the same at every posture;
  or, when the route's held-out rows showed how it grows (:mod:`selfcal.calibration.growth`), a
  smooth function of the joints that the fit matched at the calibration postures: its variance
  grows with the square of the posture's distance ``d`` (:func:`posture_distance`, a revolute
  joint's turns wrapped) from the nearest calibration posture, ``m^2 (f + (1 - f) (d /
  d_ref)^2)`` with ``m`` its size at the distance ``d_ref`` the held-out postures had and ``f``
  the share of it that does not grow,
  out to the farthest distance the held-out rows measured it and held there beyond
  (:meth:`ToolErrorModel.model_error_factor`; there it is not measured:
  :meth:`ToolErrorModel.unmeasured`).

The 95 % bound of the error's norm (position mm, orientation deg) at ``q`` is the 95 % quantile of
``|e|`` for ``e ~ N(0, S(q) + m^2 I)``, by Satterthwaite's scaled chi-square (``|e|^2 ~ a chi2_f``
with ``a = tr(Sigma^2) / tr(Sigma)``, ``f = tr(Sigma)^2 / tr(Sigma^2)``; exact for an isotropic
``Sigma``: 2.796 sigma).

The workspace is sampled in joint space (:func:`workspace_sample`): the *calibrated region* is the
box of the calibration postures' joint ranges; its *edge* is the band around it out to 10 % of
each joint's range (clipped to the joint limits); the *workspace* is the whole box of the joint
limits. SI inside; ``_mm`` / ``_deg`` at the edges.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.special import gammaincinv

from selfcal.kinematics.forward import fk_frames, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel

__all__ = [
    "Reach",
    "ToolErrorModel",
    "norm_quantile",
    "distance_growth",
    "growth_factor",
    "joint_spans",
    "posture_distance",
    "revolute_joints",
    "WorkspaceSample",
    "workspace_sample",
    "EDGE_FRACTION",
    "workspace_summary",
    "accuracy_line",
]

EDGE_FRACTION = 0.10
"""The edge band reaches this fraction of each joint's range beyond the calibrated region."""


def norm_quantile(cov: np.ndarray, p: float = 0.95) -> np.ndarray:
    """The ``p`` quantile of ``|e|`` for ``e ~ N(0, cov)``, ``cov`` (..., d, d); Satterthwaite's
    scaled chi-square (module docstring). Zero where ``cov`` is zero. The chi-square quantile is
    ``scipy.stats.chi2.ppf``'s own formula, ``2 gammaincinv(f / 2, p)`` (the same numbers), without
    importing scipy.stats (0.3-0.8 s, most of ``selfcal run``'s start-up that it does not use)."""
    cov = np.asarray(cov, dtype=float)
    tr = np.trace(cov, axis1=-2, axis2=-1)
    tr2 = np.einsum("...ij,...ji->...", cov, cov)
    ok = tr > 0
    a = np.where(ok, tr2 / np.where(ok, tr, 1.0), 0.0)
    f = np.where(ok, tr**2 / np.where(tr2 > 0, tr2, 1.0), 1.0)
    return np.sqrt(a * (2.0 * gammaincinv(f / 2.0, p)))


def distance_growth(d: np.ndarray, d_ref: float) -> np.ndarray:
    """(m,) a model error's growing variance at the distances ``d`` (m,) over its value at
    ``d_ref`` (positive): ``(d / d_ref)^2``, the ``d^2`` of the variogram the folds fit
    (:mod:`selfcal.calibration.growth`: its standard deviation grows in proportion to the
    distance; the power is assumed, not measured)."""
    return (np.asarray(d, dtype=float) / d_ref) ** 2


def growth_factor(q: np.ndarray, q_ref: np.ndarray | None, span: np.ndarray | None,
                  d_ref: float, floor: float = 0.0, limit: float = np.inf,
                  revolute: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """(m,) a model error's variance at joints ``q`` (m, n) over its variance at the distance
    ``d_ref`` from the calibration postures ``q_ref`` (k, n): ``floor + (1 - floor) (d /
    d_ref)^2`` with ``d`` the :func:`posture_distance` in units of ``span`` (n,), held at
    ``limit`` beyond it (the farthest the model error was measured; ``revolute``: the joints it
    wraps), and ``floor`` (0-1) the share of that variance that does not grow (a variogram's level,
    :mod:`selfcal.calibration.growth`); 1 everywhere when ``q_ref`` or ``span`` is None or
    ``d_ref`` is not positive (the model error the same everywhere)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q_ref is None or span is None or d_ref <= 0:
        return np.ones(len(q))
    d = np.minimum(posture_distance(q, q_ref, span, revolute), limit)
    return floor + (1.0 - floor) * distance_growth(d, d_ref)


def posture_distance(q: np.ndarray, q_ref: np.ndarray, span: np.ndarray,
                     revolute: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """(m,) every joint vector of ``q`` (m, n)'s distance to the nearest of ``q_ref`` (k, n)
    (rad / m), each joint measured in units of its ``span`` (n,) (:func:`joint_spans`: its
    limits' range, at most a turn for a revolute joint; a unit-free distance, 1 = one joint moved
    across all of its distinct postures). The joints ``revolute`` (n,) bool
    (:func:`revolute_joints`; None: none) differ by their readings' difference wrapped to
    -pi..pi: readings a whole turn apart put the links at the same pose, so a kinematic misfit is
    the same there (a UR5e's joints turn +-360 deg)."""
    q, q_ref = np.atleast_2d(q), np.atleast_2d(q_ref)
    span = np.asarray(span, dtype=float)
    wrap = np.zeros(q.shape[1], bool) if revolute is None else np.asarray(revolute, bool)
    d = np.full(len(q), np.inf)
    for r in q_ref:  # (m,) at a time: no (m, k, n) array for a large sample
        x = q - r
        x = np.where(wrap, np.remainder(x + np.pi, 2.0 * np.pi) - np.pi, x)
        d = np.minimum(d, np.linalg.norm(x / span, axis=1))
    return d


def revolute_joints(joint_types: tuple[str, ...]) -> np.ndarray:
    """(n,) bool: which of the joints ``joint_types`` (a chain's, e.g.
    :attr:`selfcal.kinematics.mcpc.MCPCModel.joint_types`) are revolute, the joints
    :func:`posture_distance` wraps."""
    return np.array([t == "revolute" for t in joint_types], bool)


def joint_spans(limits: np.ndarray, revolute: np.ndarray | None) -> np.ndarray | None:
    """(n,) the unit of :func:`posture_distance` per joint (rad / m): its range between its
    limits ``limits`` (n, 2), for the joints ``revolute`` (n,) bool (:func:`revolute_joints` of
    the chain's ``joint_types``) at most a whole turn, 2 pi (the distance wraps their
    differences to at most pi, so a UR5e joint's +-360 deg would otherwise count a half turn as
    0.125 of its range: with the cap, 1 is one joint moved across all its distinct postures);
    ``revolute`` None: no cap (the unit an older calibration file's distances were measured in).
    None when a range is not finite and positive (the model error is then taken as the same
    everywhere)."""
    span = np.diff(np.asarray(limits, dtype=float), axis=1)[:, 0]
    if revolute is not None:
        span = np.where(np.asarray(revolute, bool), np.minimum(span, 2.0 * np.pi), span)
    return span if np.all(np.isfinite(span) & (span > 0)) else None


@dataclass(frozen=True)
class Reach:
    """Where a model error grows from (module docstring): its variance at joints ``q`` is
    ``floor + (1 - floor) (d / distance)^2`` times its size's square, ``d`` the
    :func:`posture_distance` of ``q`` to ``postures`` (k, n) rad / m in units of ``span`` (n,)
    rad / m; ``distance`` (unit-free) the distance at which it has its size; ``floor``
    (0-1) the share of it that does not grow (0: none, in proportion to the distance); ``limit``
    the distance beyond which it is held (the farthest it was measured; infinite: none).
    ``distance`` 0: the model error does not grow (the same everywhere), only ``limit`` says how
    far it was measured. Which joints' turns :func:`posture_distance` wraps is not a field: it is
    the chain's own (its ``joint_types``, the one source, given to :meth:`factor`; a
    :class:`ToolErrorModel` uses its model's)."""

    postures: np.ndarray
    span: np.ndarray
    distance: float
    floor: float = 0.0
    limit: float = np.inf

    def factor(self, q: np.ndarray, joint_types: tuple[str, ...]) -> np.ndarray:
        """(m,) the model error's variance at joints ``q`` (m, n) over its size's square, the
        revolute joints of ``joint_types`` (the chain's, e.g.
        :attr:`selfcal.kinematics.mcpc.MCPCModel.joint_types`) wrapped."""
        return growth_factor(q, self.postures, self.span, self.distance, self.floor, self.limit,
                             revolute_joints(joint_types))  # fmt: skip


@dataclass(frozen=True)
class ToolErrorModel:
    """What the predicted tool error depends on (SI).

    Attributes:
        model: the calibrated chain (its tool is the tool point / frame), in its world frame.
        T_out_world: (4, 4) the output frame (e.g. the tracker's) <- the chain's world frame.
        columns: (p,) flat indices (``params.reshape(-1)``) of the estimated parameters.
        covariance: (p, p) their covariance (rad, m).
        model_error_m: per-coordinate standard deviation of the model error at the tool point (m).
        model_error_rad: the same for the tool orientation (rad, rotation-vector coordinate), or
            None when the calibration does not determine the tool frame's orientation.
        T_tool_point: (4, 4) the tool point's frame in the chain's tool frame (m), e.g. the
            flange seen from a camera that is the chain's tool; None: the tool frame itself.
        reach_postures: (k, n) the calibration postures the model error grows from, or None: the
            model error the same everywhere (module docstring).
        reach_span: (n,) the joints' spans of :func:`posture_distance` (rad / m).
        reach_distance: ``d_ref``, the distance at which the model error is ``model_error_m``.
        reach_floor: the share (0-1) of the model error's variance at ``d_ref`` that does not
            grow (:class:`Reach`).
        measured_to: the distance from the calibration postures out to which the held-out rows
            measured the model error (found or not); beyond it the model error is not measured
            (:meth:`unmeasured`) and is held at its value there. Infinite: no such limit.
    """

    model: MCPCModel
    T_out_world: np.ndarray
    columns: np.ndarray
    covariance: np.ndarray
    model_error_m: float
    model_error_rad: float | None = None
    T_tool_point: np.ndarray | None = None
    reach_postures: np.ndarray | None = None
    reach_span: np.ndarray | None = None
    reach_distance: float = 0.0
    reach_floor: float = 0.0
    measured_to: float = np.inf

    @property
    def reach(self) -> Reach | None:
        """The :class:`Reach` the model error grows from, or None (the same everywhere)."""
        if self.reach_postures is None or self.reach_span is None or self.reach_distance <= 0:
            return None
        return Reach(self.reach_postures, self.reach_span, self.reach_distance, self.reach_floor,
                     self.measured_to)  # fmt: skip

    def with_reach(self, reach: Reach | None) -> ToolErrorModel:
        """This model with its model error growing from ``reach`` (its postures, spans,
        reference distance, level's share and measured distance; the joints it wraps are this
        chain's revolute ones, :attr:`model`'s ``joint_types``), or unchanged when ``reach`` is
        None (the same everywhere)."""
        if reach is None:
            return self
        return replace(self, reach_postures=np.array(reach.postures, dtype=float),
                       reach_span=reach.span, reach_distance=reach.distance,
                       reach_floor=reach.floor, measured_to=reach.limit)  # fmt: skip

    def model_error_factor(self, q: np.ndarray) -> np.ndarray:
        """(m,) the model error's variance at joints ``q`` (m, n) over ``model_error_m^2``: 1
        everywhere, or ``floor + (1 - floor) (d / d_ref)^2`` when it grows from the calibration
        postures (module docstring)."""
        reach = self.reach
        if reach is None:
            return np.ones(len(np.atleast_2d(q)))
        return reach.factor(q, self.model.joint_types)

    def unmeasured(self, q: np.ndarray) -> np.ndarray:
        """(m,) bool: the joints ``q`` (m, n) where the model error is not measured (farther
        from the calibration postures than :attr:`measured_to`, the held-out rows' largest
        distance), whether or not the held-out rows showed one: no fold tested the model there;
        none without such a limit."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if (not np.isfinite(self.measured_to) or self.reach_postures is None
                or self.reach_span is None):  # fmt: skip
            return np.zeros(len(q), bool)
        d = posture_distance(q, self.reach_postures, self.reach_span,
                             revolute_joints(self.model.joint_types))  # fmt: skip
        return d > self.measured_to

    def _point(self) -> np.ndarray:
        """(3,) the tool point in the chain's tool frame (m)."""
        return np.zeros(3) if self.T_tool_point is None else np.asarray(self.T_tool_point)[:3, 3]

    def tool_positions(self, q: np.ndarray) -> np.ndarray:
        """Tool points (m, 3) in the output frame (m) at joints ``q`` (m, n)."""
        T = self.T_out_world @ fk_frames(self.model, q)[:, -1]
        return T[:, :3, :3] @ self._point() + T[:, :3, 3]

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(m, 6, p) derivative of ``[position (m); orientation (rad, rotation vector)]`` of the
        tool in the output frame w.r.t. the estimated parameters, at joints ``q`` (m, n)."""
        frames = fk_frames(self.model, q)
        J = identification_jacobian(self.model, q, frames)[:, :, self.columns]  # tool frame
        R = self.T_out_world[:3, :3] @ frames[:, -1, :3, :3]
        # a body twist [v; w] moves the tool point t by v + w x t (tool frame)
        t = self._point()
        skew = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
        Jp = J[:, :3] - skew @ J[:, 3:]
        return np.concatenate([R @ Jp, R @ J[:, 3:]], axis=1)

    def estimation_covariance(self, q: np.ndarray) -> np.ndarray:
        """(m, 6, 6) covariance of ``[position (m); orientation (rad)]`` of the tool in the output
        frame at joints ``q`` (m, n), from the parameters' covariance alone."""
        Jo = self.jacobian(q)
        return Jo @ self.covariance @ np.swapaxes(Jo, -1, -2)

    def predicted(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """At joints ``q`` (m, n): ``position_mm`` (m, 3) the predicted tool points (output frame),
        ``position_95_mm`` and ``estimation_95_mm`` (m,) the 95 % bound of the position error with
        and without the model error, ``position_rms_mm`` (m,) its expected RMS
        (``sqrt(tr Sigma)``), and ``orientation_95_deg`` (m,) (nan without an orientation)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        S = self.estimation_covariance(q)
        eye = self.model_error_factor(q)[:, None, None] * np.eye(3)
        Sp = S[:, :3, :3]
        Sp_tot = Sp + self.model_error_m**2 * eye
        if self.model_error_rad is None:
            rot = np.full(len(q), np.nan)
        else:
            rot = np.degrees(norm_quantile(S[:, 3:, 3:] + self.model_error_rad**2 * eye))
        return {
            "position_mm": self.tool_positions(q) * 1e3,
            "position_95_mm": norm_quantile(Sp_tot) * 1e3,
            "estimation_95_mm": norm_quantile(Sp) * 1e3,
            "position_rms_mm": np.sqrt(np.trace(Sp_tot, axis1=1, axis2=2)) * 1e3,
            "orientation_95_deg": rot,
        }


@dataclass(frozen=True)
class WorkspaceSample:
    """Joint vectors (rad / m) sampled in the three regions of the module docstring; ``box``
    (n, 2) is the calibrated region (the calibration postures' joint ranges), ``limits`` (n, 2)
    the robot's."""

    inside: np.ndarray
    edge: np.ndarray
    workspace: np.ndarray
    box: np.ndarray
    limits: np.ndarray

    def in_box(self, q: np.ndarray) -> np.ndarray:
        """Whether each joint vector of ``q`` (m, n) lies in the calibrated region."""
        q = np.atleast_2d(q)
        return np.all((q >= self.box[:, 0]) & (q <= self.box[:, 1]), axis=1)


def workspace_sample(
    q_cal: np.ndarray, limits: np.ndarray, *, count: int = 256, seed: int = 0
) -> WorkspaceSample:
    """``count`` joint vectors in each region (module docstring), uniform and deterministic
    (``seed``). An edge point is an inside point with one joint (drawn among those with room)
    moved into the band beyond the box on a side drawn among those with room; when the box
    reaches the limits on every side the edge sample is empty.

    ``q_cal`` (m, n): the calibration postures; ``limits`` (n, 2): the joint limits (rad / m).
    """
    q_cal = np.atleast_2d(np.asarray(q_cal, dtype=float))
    limits = np.asarray(limits, dtype=float)
    n = limits.shape[0]
    rng = np.random.default_rng(seed)
    box = np.stack([q_cal.min(axis=0), q_cal.max(axis=0)], axis=1)
    inside = rng.uniform(box[:, 0], box[:, 1], (count, n))
    band = EDGE_FRACTION * (limits[:, 1] - limits[:, 0])
    lo = np.stack([np.maximum(box[:, 0] - band, limits[:, 0]), box[:, 0]], axis=1)  # below
    hi = np.stack([box[:, 1], np.minimum(box[:, 1] + band, limits[:, 1])], axis=1)  # above
    sides = np.stack([lo, hi])  # (2, n, 2): side, joint, [from, to]
    room = sides[:, :, 1] - sides[:, :, 0] > 1e-12  # (2, n)
    options = np.argwhere(room.T)  # (k, 2): joint, side
    if options.size == 0:
        edge = np.zeros((0, n))
    else:
        pick = options[rng.integers(0, len(options), count)]
        edge = rng.uniform(box[:, 0], box[:, 1], (count, n))
        j, s = pick[:, 0], pick[:, 1]
        a, b = sides[s, j, 0], sides[s, j, 1]
        edge[np.arange(count), j] = a + rng.uniform(0.0, 1.0, count) * (b - a)
    workspace = rng.uniform(limits[:, 0], limits[:, 1], (count, n))
    return WorkspaceSample(inside, edge, workspace, box, limits)


def _region(em: ToolErrorModel, q: np.ndarray) -> dict:
    """Largest and median 95 % bounds and the RMS over the joint vectors ``q`` (mm, deg)."""
    if len(q) == 0:
        return {"points": 0}
    pred = em.predicted(q)
    p95, rot = pred["position_95_mm"], pred["orientation_95_deg"]
    out = {
        "points": int(p95.size),
        "position_95_mm_max": float(p95.max()),
        "position_95_mm_median": float(np.median(p95)),
        "position_rms_mm": float(np.sqrt(np.mean(pred["position_rms_mm"] ** 2))),
    }
    if np.all(np.isfinite(rot)):
        out["orientation_95_deg_max"] = float(rot.max())
        out["orientation_95_deg_median"] = float(np.median(rot))
    far = em.unmeasured(q)
    if far.any():
        out["model_error_not_measured_share"] = float(np.mean(far))
    return out


def workspace_summary(em: ToolErrorModel, sample: WorkspaceSample, q_cal: np.ndarray) -> dict:
    """The predicted errors over the regions of ``sample`` and at the calibration postures
    ``q_cal`` (m, n): per region its point count, the largest and the median 95 % bound (mm,
    deg) and the RMS over it (mm), and the share of its points where the model error is not
    measured (:meth:`ToolErrorModel.unmeasured`) when there are any; at the postures also each
    one's 95 % bounds."""
    out = {name: _region(em, getattr(sample, name)) for name in ("inside", "edge", "workspace")}
    at_cal = em.predicted(q_cal)
    out["calibration_postures"] = {
        **_region(em, q_cal),
        "position_95_mm": at_cal["position_95_mm"].tolist(),
    }
    if np.all(np.isfinite(at_cal["orientation_95_deg"])):
        out["calibration_postures"]["orientation_95_deg"] = at_cal["orientation_95_deg"].tolist()
    return out


def accuracy_line(regions: dict) -> str:
    """The one line of a report on a :func:`workspace_summary`: the largest 95 % bound of the
    tool point's position inside the calibrated region and at its edge (mm), and of the tool's
    orientation when predicted (deg); and the share of each region (inside, edge, workspace)
    where the model error is not measured, when there is one: the edge's figure rests on it too
    (the photoneo set's line named the workspace's 100 % alone, whose figure it does not give,
    and not the edge's 31 %)."""
    inside, edge = regions["inside"], regions["edge"]
    text = (
        f"tool point within {inside['position_95_mm_max']:.3f} mm (95 %) inside the calibrated "
        "region"
    )
    if edge.get("points"):
        text += f", {edge['position_95_mm_max']:.3f} mm at its edge"
    else:
        text += " (it reaches the joint limits: no edge)"
    if "orientation_95_deg_max" in inside:
        text += f"; orientation within {inside['orientation_95_deg_max']:.4f} deg"
        if "orientation_95_deg_max" in edge:
            text += f", {edge['orientation_95_deg_max']:.4f} deg at the edge"
    far = [
        f"{share:.0%} of the {name}'s points"
        for name in ("inside", "edge", "workspace")
        if (share := (regions.get(name) or {}).get("model_error_not_measured_share"))
    ]
    if far:
        text += (
            f"; the model error is not measured at {', '.join(far)} (farther from the "
            "calibration postures than the cross-validation reached: held at its value there)"
        )
    return text
