"""Residual blocks of external measurements of the tool: tracker positions, poses and distances.

A laser tracker, an optical tracker or a CMM measures the robot's tool in its own frame (the
*tracker* frame): the 3-D position of a tool point, the full pose of a tool frame, or the
distance between the tool point at two configurations (ball bar, a known length). Each kind is
one residual block for :mod:`selfcal.solver`, with the analytic Jacobian from the MCPC
identification Jacobian (:func:`selfcal.kinematics.forward.identification_jacobian`: the body twist of the
tool frame per parameter).

Where the unknowns live (:class:`ChainLayout`): the MCPC parameters are coordinates of one
parameter block (``coords``: the flat parameter -> block coordinate map, -1 for parameters fixed
at the template model's value). Optionally the tracker frame is a separate 6-vector block
``[w, v]`` with ``T_tracker_world = [Rot(w) R0, t0 + v]`` (when the chain's world is not the
tracker frame, e.g. the cameras' reconstruction frame of the joint refinement), and the tool
point a 3-vector block in the model's tool frame. Without them the tracker frame is the chain's
world and the tool point is the origin of the model's tool frame (``V_n`` carries the offset).

Residuals, each in units of its own standard deviation:
- position: ``(y - p) / sigma`` (3 per row), ``y = T_tracker_world T_world_tool(q) s``;
- pose: ``pose_error(T_pred, T_meas) / [sigma_t, sigma_r]`` (6 per row; translation and
  rotation vector in the predicted tool frame, :func:`selfcal.kinematics.forward.pose_error`);
- distance: ``(|y_a - y_b| - d) / sigma`` (1 per row).

Also here: the measurements as data (:class:`TrackerMeasurements`), the closed-form start
(:mod:`selfcal.estimation.tracker_start`) and the blocks another problem adds to take tracker data in
(:func:`tracker_terms`, used by the joint refinement over images).

Units: SI (m, rad).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from selfcal.errors import InputError, UsageError
from selfcal.estimation.pose_models import so3_left_jacobian
from selfcal.estimation.tracker_start import initial_placement, mean_rotation, pose_placement
from selfcal.kinematics.forward import (
    fk_frames,
    identification_jacobian,
    pose_error,
    pose_error_jacobian,
)
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.solver import Evaluation, JacobianPiece, Loss, ParameterBlock
from selfcal.transforms import adjoint, inv_pose, make_pose, pose_from_vec, skew

__all__ = [
    "TrackerMeasurements",
    "initial_placement",
    "mean_rotation",
    "tracker_terms",
    "restarted",
    "tracker_report",
    "ChainLayout",
    "TrackerPositionBlock",
    "TrackerPoseBlock",
    "TrackerDistanceBlock",
]


@dataclass(frozen=True)
class ChainLayout:
    """Where a tracker block finds its unknowns (see the module docstring).

    Attributes:
        model: template chain; parameters not in ``block`` keep its values (rad, m).
        block: name of the parameter block holding MCPC parameters.
        coords: (6 (n + 1),) coordinate in ``block`` of each flat MCPC parameter
            (``model.params.reshape(-1)`` order), -1 = fixed at the template's value.
        frame: name of the 6-vector block ``[w (rad), v (m)]`` of the tracker frame, or None
            (tracker frame = the chain's world).
        frame0: ``T0_tracker_world`` (4, 4) around which ``frame`` perturbs.
        point: name of the 3-vector block of the tool point in the model's tool frame (m), or
            None (``point0`` fixed).
        point0: (3,) the fixed tool point when ``point`` is None (m).
        tool: name of the 6-vector block ``[w, v]`` of the measured tool frame in the model's
            tool frame (for poses), perturbing ``tool0`` like ``frame``; or None (``tool0``).
        tool0: (4, 4) ``T0_modeltool_measuredtool``.
    """

    model: MCPCModel
    block: str
    coords: np.ndarray
    frame: str | None = None
    frame0: np.ndarray = field(default_factory=lambda: np.eye(4))
    point: str | None = None
    point0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tool: str | None = None
    tool0: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        c = np.asarray(self.coords, dtype=np.int64).reshape(-1)
        if c.shape != (6 * (self.model.n + 1),):
            raise UsageError(f"coords must have {6 * (self.model.n + 1)} entries, got {c.size}")
        object.__setattr__(self, "coords", c)
        object.__setattr__(self, "frame0", np.asarray(self.frame0, dtype=float))
        object.__setattr__(self, "tool0", np.asarray(self.tool0, dtype=float))
        object.__setattr__(self, "point0", np.asarray(self.point0, dtype=float).reshape(3))

    @classmethod
    def whole(cls, model: MCPCModel, block: str = "mcpc") -> ChainLayout:
        """All flat MCPC parameters as coordinates ``0 .. 6n + 5`` of ``block`` (hold some with
        the parameter block's ``held`` mask); tracker frame = world, tool point = tool origin."""
        return cls(model, block, np.arange(6 * (model.n + 1)))

    # ------------------------------------------------------------------ evaluation
    def chain(self, values: Mapping[str, np.ndarray]) -> MCPCModel:
        """The MCPC model at the parameter values."""
        flat = self.model.params.reshape(-1).copy()
        sel = self.coords >= 0
        flat[sel] = values[self.block][self.coords[sel]]
        return self.model.with_params(flat)

    def tracker_frame(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """``T_tracker_world`` (4, 4) at the parameter values."""
        return np.eye(4) if self.frame is None else _perturbed(self.frame0, values[self.frame])

    def tool_frame(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """``T_modeltool_measuredtool`` (4, 4) at the parameter values."""
        return self.tool0 if self.tool is None else _perturbed(self.tool0, values[self.tool])

    def tool_point(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """The tool point (3,) in the model's tool frame (m)."""
        return self.point0 if self.point is None else values[self.point]

    def _kin_columns(self) -> tuple[np.ndarray, np.ndarray]:
        sel = np.flatnonzero(self.coords >= 0)
        return sel, self.coords[sel]

    def points(
        self, values: Mapping[str, np.ndarray], q: np.ndarray, jacobian: bool
    ) -> tuple[np.ndarray, list[tuple[str, np.ndarray, np.ndarray]]]:
        """Tool points ``y`` (m, 3) in the tracker frame at joints ``q`` (m, n) and, when
        ``jacobian``, their derivatives ``(block, dy (m, 3, c), block coordinates (c,))``."""
        mdl = self.chain(values)
        frames = fk_frames(mdl, q)
        T = frames[:, -1]
        s = self.tool_point(values)
        x = T[:, :3, :3] @ s + T[:, :3, 3]
        Tf = self.tracker_frame(values)
        y = x @ Tf[:3, :3].T + Tf[:3, 3]
        if not jacobian:
            return y, []
        sel, cols = self._kin_columns()
        J = identification_jacobian(mdl, q, frames)[:, :, sel]
        RfR = Tf[:3, :3] @ T[:, :3, :3]  # (m, 3, 3)
        pieces = [(self.block, RfR @ (J[:, :3] - skew(s) @ J[:, 3:]), cols)]
        if self.point is not None:
            pieces.append((self.point, RfR, np.arange(3)))
        if self.frame is not None:
            Jl = so3_left_jacobian(values[self.frame][:3])
            dw = -skew(y - Tf[:3, 3]) @ Jl
            dv = np.broadcast_to(np.eye(3), dw.shape)
            pieces.append((self.frame, np.concatenate([dw, dv], axis=-1), np.arange(6)))
        return y, pieces

    def poses(
        self, values: Mapping[str, np.ndarray], q: np.ndarray, jacobian: bool
    ) -> tuple[np.ndarray, list[tuple[str, np.ndarray, np.ndarray]]]:
        """Tool poses ``T_tracker_tool`` (m, 4, 4) at joints ``q`` (m, n) and, when
        ``jacobian``, their body twists ``[v; w]`` per unknown ``(block, (m, 6, c), coords)``."""
        mdl = self.chain(values)
        Tf, Tt = self.tracker_frame(values), self.tool_frame(values)
        frames = fk_frames(mdl, q)
        T = Tf @ frames[:, -1] @ Tt
        if not jacobian:
            return T, []
        sel, cols = self._kin_columns()
        to_tool = adjoint(inv_pose(Tt))  # model-tool twists -> measured-tool twists
        J = to_tool @ identification_jacobian(mdl, q, frames)[:, :, sel]
        pieces = [(self.block, J, cols)]
        if self.frame is not None:
            spatial = _spatial_jacobian(Tf, values[self.frame])
            pieces.append((self.frame, adjoint(inv_pose(T)) @ spatial, np.arange(6)))
        if self.tool is not None:
            spatial = _spatial_jacobian(Tt, values[self.tool])
            pieces.append(
                (self.tool, np.broadcast_to(to_tool @ spatial, J.shape[:2] + (6,)), np.arange(6))
            )
        return T, pieces


def _perturbed(T0: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """``[Rot(w) R0, t0 + v]`` for ``wv = [w (rad), v (m)]``."""
    R = pose_from_vec(np.r_[wv[:3], 0.0, 0.0, 0.0])[:3, :3] @ T0[:3, :3]
    return make_pose(R, T0[:3, 3] + wv[3:])


def _spatial_jacobian(T: np.ndarray, wv: np.ndarray) -> np.ndarray:
    """(6, 6): the twist ``[e_t; phi]`` with ``dT = [e]^ T`` of ``T = _perturbed(T0, wv)`` per
    ``[dw, dv]``: ``phi = J_l(w) dw`` and ``e_t = dv - phi x t``."""
    Jl = so3_left_jacobian(wv[:3])
    out = np.zeros((6, 6))
    out[:3, :3] = skew(T[:3, 3]) @ Jl
    out[:3, 3:] = np.eye(3)
    out[3:, :3] = Jl
    return out


def _pieces(
    raw: list[tuple[str, np.ndarray, np.ndarray]], k: int, scale: np.ndarray | float
) -> tuple[JacobianPiece, ...]:
    out = []
    for block, J, cols in raw:
        J = np.asarray(J) * (np.asarray(scale)[..., None] if np.ndim(scale) else scale)
        out.append(JacobianPiece(block, J, np.broadcast_to(cols, (k, len(cols)))))
    return tuple(out)


class _TrackerBlock:
    """What the tracker blocks share: name, loss, layout and the joint rows ``q`` (k, n)."""

    def __init__(self, layout: ChainLayout, q: np.ndarray, name: str, loss: Loss | None) -> None:
        self.name = name
        self.loss = loss or Loss()
        self.layout = layout
        self.q = np.atleast_2d(np.asarray(q, dtype=float))


class TrackerPositionBlock(_TrackerBlock):
    """Rows ``(y_i - p_i) / sigma_i`` (3 each): measured tool-point positions ``p`` (m, 3) m in
    the tracker frame at joints ``q`` (m, n) rad / m; ``sigma`` m (scalar, (m,) or (m, 3))."""

    dim = 3

    def __init__(
        self,
        layout: ChainLayout,
        q: np.ndarray,
        p: np.ndarray,
        sigma: float | np.ndarray,
        *,
        name: str = "tracker_positions",
        loss: Loss | None = None,
    ) -> None:
        super().__init__(layout, q, name, loss)
        self.p = np.asarray(p, dtype=float).reshape(-1, 3)
        s = np.asarray(sigma, dtype=float)
        self.w = 1.0 / np.broadcast_to(s[:, None] if s.ndim == 1 else s, self.p.shape)

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (m, 3) and the pieces of the chain (and frame, point) blocks."""
        y, raw = self.layout.points(values, self.q, jacobian)
        r = (y - self.p) * self.w
        return Evaluation(r, _pieces(raw, len(r), self.w) if jacobian else ())


class TrackerPoseBlock(_TrackerBlock):
    """Rows ``pose_error(T_pred_i, T_i) / sigma`` (6 each, ``[d; delta]`` in the predicted tool
    frame): measured tool poses ``T`` (m, 4, 4) in the tracker frame at joints ``q``;
    ``sigma_t`` m and ``sigma_r`` rad (scalars, (m,) or per axis (m, 3))."""

    dim = 6

    def __init__(
        self,
        layout: ChainLayout,
        q: np.ndarray,
        T: np.ndarray,
        sigma_t: float | np.ndarray,
        sigma_r: float | np.ndarray,
        *,
        name: str = "tracker_poses",
        loss: Loss | None = None,
    ) -> None:
        super().__init__(layout, q, name, loss)
        self.T = np.asarray(T, dtype=float).reshape(-1, 4, 4)
        m = len(self.T)

        def per_axis(s: float | np.ndarray) -> np.ndarray:
            a = np.asarray(s, dtype=float)
            return np.broadcast_to(a[:, None] if a.ndim == 1 else a, (m, 3))

        self.w = 1.0 / np.concatenate([per_axis(sigma_t), per_axis(sigma_r)], axis=1)

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (m, 6) and the pieces (exact derivative of the pose error)."""
        T, raw = self.layout.poses(values, self.q, jacobian)
        y = pose_error(T, self.T)
        r = y * self.w
        if not jacobian:
            return Evaluation(r)
        raw = [(b, -pose_error_jacobian(J, y), c) for b, J, c in raw]
        return Evaluation(r, _pieces(raw, len(r), self.w))


class TrackerDistanceBlock(_TrackerBlock):
    """Rows ``(|y(q_a) - y(q_b)| - d) / sigma`` (1 each): measured distances ``d`` (k,) m between
    the tool point at joints ``q_a`` and ``q_b`` (k, n); ``sigma`` m (scalar or (k,))."""

    dim = 1

    def __init__(
        self,
        layout: ChainLayout,
        q_a: np.ndarray,
        q_b: np.ndarray,
        d: np.ndarray,
        sigma: float | np.ndarray,
        *,
        name: str = "tracker_distances",
        loss: Loss | None = None,
    ) -> None:
        super().__init__(
            layout, np.concatenate([np.atleast_2d(q_a), np.atleast_2d(q_b)]), name, loss
        )
        self.d = np.asarray(d, dtype=float).reshape(-1)
        self.w = 1.0 / np.broadcast_to(np.asarray(sigma, dtype=float), self.d.shape)

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (k, 1) and the pieces (unit direction times the point derivatives)."""
        k = len(self.d)
        y, raw = self.layout.points(values, self.q, jacobian)
        u = y[:k] - y[k:]
        dist = np.linalg.norm(u, axis=1)
        r = ((dist - self.d) * self.w)[:, None]
        if not jacobian:
            return Evaluation(r)
        e = u / np.maximum(dist, 1e-300)[:, None]
        out = [(b, np.einsum("ki,kic->kc", e, J[:k] - J[k:])[:, None, :], c) for b, J, c in raw]
        return Evaluation(r, _pieces(out, k, self.w[:, None]))


@dataclass(frozen=True)
class TrackerMeasurements:
    """Tracker data in the tracker frame, SI units.

    Attributes:
        q: (m, n) joint readings of the position/pose rows (rad, m); (0, n) when there are none.
        xyz: (m, 3) measured tool-point positions (m).
        R: (m, 3, 3) measured tool-frame orientations, or None (positions only).
        q_a, q_b: (k, n) joint readings of the two ends of each distance (or None).
        d: (k,) measured distances (m) between the tool point at ``q_a`` and ``q_b`` (or None).
    """

    q: np.ndarray
    xyz: np.ndarray
    R: np.ndarray | None = None
    q_a: np.ndarray | None = None
    q_b: np.ndarray | None = None
    d: np.ndarray | None = None

    @property
    def m(self) -> int:
        """Number of position / pose rows."""
        return int(len(self.q))

    @property
    def k(self) -> int:
        """Number of distances."""
        return 0 if self.d is None else int(len(self.d))

    def equations(self) -> int:
        """Scalar equations: 3 per position, 6 per pose, 1 per distance."""
        return (6 if self.R is not None else 3) * self.m + self.k

    def with_rows(self, keep: np.ndarray) -> TrackerMeasurements:
        """The position / pose rows selected by ``keep`` (a mask or indices), every distance
        row kept (a cross-validation fold's training set)."""
        R = None if self.R is None else self.R[keep]
        return TrackerMeasurements(self.q[keep], self.xyz[keep], R, self.q_a, self.q_b, self.d)

    def distances(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_a, q_b, d)`` of the distance rows ((k, n), (k, n), (k,)); empty when none."""
        if self.q_a is None or self.q_b is None or self.d is None:
            n = self.q.shape[1]
            return np.zeros((0, n)), np.zeros((0, n)), np.zeros(0)
        return self.q_a, self.q_b, self.d

    def check(self, n: int) -> None:
        """Raise :class:`selfcal.errors.InputError` for shapes that do not fit ``n`` joints or
        non-finite numbers (the readers in :mod:`selfcal.io.tracker` name file, row and column)."""
        arrays: dict[str, tuple[np.ndarray | None, tuple[int, ...]]] = {
            "q": (self.q, (self.m, n)),
            "xyz": (self.xyz, (self.m, 3)),
        }
        if self.R is not None:
            arrays["R"] = (self.R, (self.m, 3, 3))
        if self.d is not None:
            arrays |= {"q_a": (self.q_a, (self.k, n)), "q_b": (self.q_b, (self.k, n))}
        for key, (a, shape) in arrays.items():
            if a is None or np.shape(a) != shape:
                raise InputError(
                    f"tracker data: {key} must have shape {shape}, got "
                    f"{None if a is None else a.shape}"
                )
            if not np.all(np.isfinite(a)):
                raise InputError(f"tracker data: {key} holds NaN or inf")
        if self.m + self.k == 0:
            raise InputError("tracker data: no measurements")


def tracker_terms(
    meas: TrackerMeasurements,
    model: MCPCModel,
    free_idx: np.ndarray,
    block: str,
    sigma: float,
    sigma_r: float | None = None,
) -> tuple[list, list[ParameterBlock]]:
    """Residual and parameter blocks that add tracker positions, poses and distances to another
    problem (e.g. the joint refinement over images): its parameter block ``block`` holds the
    flat MCPC parameters ``free_idx`` of ``model`` as its first coordinates (the others fixed at
    ``model``'s values). New unknowns: the tracker frame (block ``tracker_frame``, with positions
    or poses; started at :func:`initial_placement`), the tool point in ``model``'s tool frame
    (``tool_point``, m; positions and distances) and, for poses, the measured tool frame in
    ``model``'s tool frame (``tool_frame``, ``[w, v]``). ``sigma``: the residuals' scale (m per
    unit of residual), ``sigma_r`` that of the rotations of poses (rad per unit).
    """
    coords = -np.ones(6 * (model.n + 1), np.int64)
    coords[np.asarray(free_idx)] = np.arange(len(free_idx))
    frame0, tool0, params = np.eye(4), np.eye(4), []
    poses = meas.m > 0 and meas.R is not None
    if poses:  # the closed form of the poses: the positions' start fails with few rows
        frame0, tool0 = pose_placement(model, meas.q, make_pose(np.asarray(meas.R), meas.xyz))
    elif meas.m:
        frame0, s0 = initial_placement(model, meas.q, meas.xyz)
        tool0 = make_pose(np.eye(3), s0)
    if meas.m:
        params.append(ParameterBlock("tracker_frame", np.zeros(6)))
    if poses:
        params.append(ParameterBlock("tool_frame", np.zeros(6)))
    if meas.k or not poses:
        params.append(ParameterBlock("tool_point", tool0[:3, 3]))
    layout = ChainLayout(
        model,
        block,
        coords,
        frame="tracker_frame" if meas.m else None,
        frame0=frame0,
        point="tool_point" if meas.k or not poses else None,
        tool="tool_frame" if poses else None,
        tool0=tool0,
    )
    blocks: list = []
    if poses:
        T = make_pose(np.asarray(meas.R), meas.xyz)
        if sigma_r is None:
            raise InputError("tracker poses need sigma_r (rad per unit of residual)")
        blocks.append(TrackerPoseBlock(layout, meas.q, T, sigma, sigma_r))
    elif meas.m:
        blocks.append(TrackerPositionBlock(layout, meas.q, meas.xyz, sigma))
    if meas.k:
        blocks.append(TrackerDistanceBlock(layout, *meas.distances(), sigma))
    return blocks, params


def restarted(
    params: list[ParameterBlock], values: Mapping[str, np.ndarray]
) -> list[ParameterBlock]:
    """The parameter blocks ``params`` started at ``values`` instead (e.g. a solution's, for the
    next round of an adjustment)."""
    return [ParameterBlock(p.name, values[p.name], p.held, p.instance) for p in params]


def tracker_report(
    blocks: list,
    params: list[ParameterBlock],
    values: Mapping[str, np.ndarray],
    residuals: Mapping[str, np.ndarray],
    scale_m: float,
) -> dict:
    """What :func:`tracker_terms` estimated: ``<block>_rms_m``, the RMS (m) of the translation
    part of each tracker residual block's rows (``residuals`` in units of ``scale_m`` m), and the
    estimated ``tracker_frame`` (``T_tracker_world``, 4 x 4, m), ``tool_frame``
    (``T_modeltool_measuredtool``) and ``tool_point`` (m), as lists."""
    out: dict = {}
    for b in blocks:
        r = residuals[b.name][:, :3] * scale_m
        out[f"{b.name}_rms_m"] = float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
    if blocks:
        lay = blocks[0].layout
        get = {lay.frame: lay.tracker_frame, lay.tool: lay.tool_frame, lay.point: lay.tool_point}
        out |= {p.name: get[p.name](values).tolist() for p in params}
    return out
