"""Residual blocks of external measurements of the tool: tracker positions, poses and distances.

A laser tracker, an optical tracker or a CMM measures the robot's tool in its own frame (the
*tracker* frame): the 3-D position of a tool point, the full pose of a tool frame, or the
distance between the tool point at two configurations (ball bar, a known length). Each kind is
one residual block for :mod:`calib.solver`, with the analytic Jacobian from the MCPC
identification Jacobian (:func:`calib.kinematics.identification_jacobian`: the body twist of the
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
  rotation vector in the predicted tool frame, :func:`calib.kinematics.pose_error`);
- distance: ``(|y_a - y_b| - d) / sigma`` (1 per row).

Also here: the measurements as data (:class:`TrackerMeasurements`), the closed-form start
(:func:`initial_placement`) and the blocks another problem adds to take tracker data in
(:func:`tracker_terms`, used by the joint refinement over images).

Units: SI (m, rad).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from calib.errors import InputError
from calib.estimation.pose_models import so3_left_jacobian
from calib.identify import pose_error_jacobian
from calib.kinematics import fk_frames, fk_tool, identification_jacobian, pose_error
from calib.mcpc import MCPCModel
from calib.solver import Evaluation, JacobianPiece, Loss, ParameterBlock
from calib.transforms import adjoint, inv_pose, kabsch, make_pose, pose_from_vec, skew

__all__ = [
    "TrackerMeasurements",
    "initial_placement",
    "mean_rotation",
    "tracker_terms",
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
    """

    model: MCPCModel
    block: str
    coords: np.ndarray
    frame: str | None = None
    frame0: np.ndarray = field(default_factory=lambda: np.eye(4))
    point: str | None = None
    point0: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        c = np.asarray(self.coords, dtype=np.int64).reshape(-1)
        if c.shape != (6 * (self.model.n + 1),):
            raise ValueError(f"coords must have {6 * (self.model.n + 1)} entries, got {c.size}")
        object.__setattr__(self, "coords", c)
        object.__setattr__(self, "frame0", np.asarray(self.frame0, dtype=float))
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
        if self.frame is None:
            return np.eye(4)
        wv = values[self.frame]
        R = pose_from_vec(np.r_[wv[:3], 0.0, 0.0, 0.0])[:3, :3] @ self.frame0[:3, :3]
        return make_pose(R, self.frame0[:3, 3] + wv[3:])

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
        Tf = self.tracker_frame(values)
        frames = fk_frames(mdl, q)
        T = Tf @ frames[:, -1]
        if not jacobian:
            return T, []
        sel, cols = self._kin_columns()
        pieces = [(self.block, identification_jacobian(mdl, q, frames)[:, :, sel], cols)]
        if self.frame is not None:
            Jl = so3_left_jacobian(values[self.frame][:3])
            spatial = np.zeros((6, 6))  # [e_t; phi] per [dw, dv]
            spatial[:3, :3] = skew(Tf[:3, 3]) @ Jl
            spatial[:3, 3:] = np.eye(3)
            spatial[3:, :3] = Jl
            pieces.append((self.frame, adjoint(inv_pose(T)) @ spatial, np.arange(6)))
        return T, pieces


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
    ``sigma_t`` m and ``sigma_r`` rad (scalars or (m,))."""

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
        st = np.broadcast_to(np.asarray(sigma_t, dtype=float), (m,))
        sr = np.broadcast_to(np.asarray(sigma_r, dtype=float), (m,))
        self.w = 1.0 / np.column_stack([st, st, st, sr, sr, sr])

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

    def distances(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_a, q_b, d)`` of the distance rows ((k, n), (k, n), (k,)); empty when none."""
        if self.q_a is None or self.q_b is None or self.d is None:
            n = self.q.shape[1]
            return np.zeros((0, n)), np.zeros((0, n)), np.zeros(0)
        return self.q_a, self.q_b, self.d

    def check(self, n: int) -> None:
        """Raise :class:`calib.errors.InputError` for shapes that do not fit ``n`` joints or
        non-finite numbers (the readers in :mod:`calib.io.tracker` name file, row and column)."""
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


def initial_placement(
    model: MCPCModel, q: np.ndarray, xyz: np.ndarray, *, iterations: int = 50
) -> tuple[np.ndarray, np.ndarray]:
    """``(T_meas_base (4, 4), s (3,))``: the rigid placement of ``model`` in the tracker frame and
    the tool point ``s`` in its tool frame (m) that best fit the positions ``xyz`` (m, 3) at
    ``q`` (m, n), by alternating the closed-form rigid fit (Kabsch) with the linear
    least-squares tool point (a fixed-point start for the estimation, not an estimate)."""
    T = fk_tool(model, q)
    s = np.zeros(3)
    B = np.eye(4)
    for _ in range(iterations):
        x = T[:, :3, :3] @ s + T[:, :3, 3]
        B = kabsch(x, xyz) if len(q) >= 3 else make_pose(np.eye(3), np.mean(xyz - x, axis=0))
        rhs = (xyz - B[:3, 3]) @ B[:3, :3] - T[:, :3, 3]  # R_i s = B^-1 p_i - t_i
        s_new = np.linalg.lstsq(T[:, :3, :3].reshape(-1, 3), rhs.reshape(-1), rcond=None)[0]
        done = np.linalg.norm(s_new - s) <= 1e-6  # a start for LM: 1 um is plenty
        s = s_new
        if done:
            break
    return B, s


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """The chordal mean (3, 3) of rotations ``R`` (m, 3, 3): the proper rotation nearest their sum."""
    U, _, Vt = np.linalg.svd(np.sum(R, axis=0))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def tracker_terms(
    meas: TrackerMeasurements,
    model: MCPCModel,
    free_idx: np.ndarray,
    block: str,
    sigma: float,
) -> tuple[list, list[ParameterBlock]]:
    """Residual and parameter blocks that add tracker positions and distances to another
    problem (e.g. the joint refinement over images): its parameter block ``block`` holds the
    flat MCPC parameters ``free_idx`` of ``model`` as its first coordinates (the others fixed at
    ``model``'s values). New unknowns: the tracker frame (block ``tracker_frame``, only with
    positions; started at :func:`initial_placement`) and the tool point in ``model``'s tool
    frame (``tool_point``, m). ``sigma``: the residuals' scale (m per unit of residual).

    Raises:
        InputError: pose rows (their tool frame would need its own 6-dof offset; give positions).
    """
    if meas.R is not None:
        raise InputError(
            "tracker poses cannot be combined with images yet",
            fix="give the tracker's positions (x_mm, y_mm, z_mm) without the quaternion",
        )
    coords = -np.ones(6 * (model.n + 1), np.int64)
    coords[np.asarray(free_idx)] = np.arange(len(free_idx))
    frame0, s0, params = np.eye(4), np.zeros(3), []
    if meas.m:
        frame0, s0 = initial_placement(model, meas.q, meas.xyz)
        params.append(ParameterBlock("tracker_frame", np.zeros(6)))
    params.append(ParameterBlock("tool_point", s0))
    frame = "tracker_frame" if meas.m else None
    layout = ChainLayout(model, block, coords, frame=frame, frame0=frame0, point="tool_point")
    blocks: list = []
    if meas.m:
        blocks.append(TrackerPositionBlock(layout, meas.q, meas.xyz, sigma))
    if meas.k:
        blocks.append(TrackerDistanceBlock(layout, *meas.distances(), sigma))
    return blocks, params
