"""Camera poses from the kinematic chain: the pose model of the one-step refinement.

Frames: ``T_world_cam`` of the rig's first camera (the left one) is the MCPC tool (OpenCV camera
frame); camera ``c`` of the rig is ``T_cam_first @ T_first_world``. Eye-to-hand (the cameras
static, the target on the flange) inverts the chain: its world is the first camera and its tool
the target, so the chain gives ``T_first_target`` itself. Views are indexed by
:class:`selfcal.estimation.observations.ViewLayout`. SI units.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from selfcal.errors import UsageError
from selfcal.estimation.observations import ViewLayout
from selfcal.estimation.pose_models import so3_left_jacobian
from selfcal.kinematics.forward import fk_frames, fk_tool, identification_jacobian
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.transforms import adjoint, inv_pose, make_pose, pose_from_vec, skew

__all__ = ["KinematicPoses", "joint_twists"]


class KinematicPoses:
    """Camera poses from the kinematic chain: a :class:`selfcal.estimation.pose_models.PoseModel`.

    Configuration ``i`` (with ``active[i]``): first camera ``T_world_cam = fk_tool(model(rho),
    q_i)`` (the model's tool is the first camera, OpenCV frame), camera ``c`` of the rig
    ``T_cam_world = T_cam_first @ T_first_world`` (stereo: ``T_right_left``). Inactive
    configurations have NaN poses and no parameters.

    Parameters ``p = [rho_free (k), rig (6 per further camera)]``: ``rho_free`` the *absolute*
    values (rad, m) of the flat MCPC parameters ``free_idx`` (indices into
    ``model.params.reshape(-1)``, all others fixed at ``model``'s values), each ``rig = [w, v]``
    the left-perturbation of ``T_cam_first`` around ``T0_cam_first``: ``R = Rot(w) R0``,
    ``t = t0 + v``.

    ``offset_joints`` (indices of revolute joints, 0-based): their zero offsets are estimated
    too, as changes (rad) of ``model.joint_offsets`` right after ``rho_free`` (the parameter
    ``p`` then reads ``[rho_free, offsets, rig, dq]``).

    With ``joint_corrections=True`` the parameters continue with ``dq`` (n per active
    configuration, rad / m): the poses use ``q_i + dq_i`` (errors in the joint read-back, e.g.
    encoder quantisation; the caller adds a prior on ``dq``). ``dq_cols`` are their indices in
    ``p``.

    ``eye_to_hand=True``: the cameras are static and the target rides on the flange; the
    chain's world is the first camera and its tool the target, so the first camera's view pose
    is the chain's tool pose itself, ``T_cam_world = fk_tool(model(rho), q_i)`` (the world of the
    views is the target frame), and camera ``c``'s ``T_cam_first @ T_first_target`` as above.

    ``view_jacobian`` is analytic: the identification Jacobian is the body twist ``xi`` of
    ``T_world_cam``  (``dT = T xi^``), so ``T_cam_world`` moves by the camera-frame twist ``-xi``
    (the bundle adjustment's convention); camera ``c`` by ``Ad(T_cam_first) (-xi)``. Eye-to-hand
    the chain's tool pose ``T`` is the view pose, which moves by the camera-frame twist
    ``Ad(T) xi`` (``T xi^ = (Ad(T) xi)^ T``). The joint columns are the joint axes' twists in the
    tool frame.
    """

    def __init__(
        self,
        model: MCPCModel,
        q: np.ndarray,
        free_idx: np.ndarray,
        T0_cam_first: np.ndarray,
        active: np.ndarray | None = None,
        *,
        joint_corrections: bool = False,
        offset_joints: np.ndarray | tuple[int, ...] = (),
        eye_to_hand: bool = False,
    ):
        self.model = model
        self.eye_to_hand = bool(eye_to_hand)
        self.q = np.atleast_2d(np.asarray(q, dtype=float))
        if self.q.shape[1] != model.n:
            raise UsageError(f"q must have shape (m, {model.n}) (rad), got {self.q.shape}")
        self.free_idx = np.asarray(free_idx, dtype=np.int64)
        if len(np.unique(self.free_idx)) != len(self.free_idx):
            raise UsageError("free_idx contains duplicates")
        self.offset_joints = np.asarray(offset_joints, dtype=np.int64).reshape(-1)
        if any(model.joint_types[j] != "revolute" for j in self.offset_joints.tolist()):
            raise UsageError("offset_joints must name revolute joints")
        self.rigs0 = np.asarray(T0_cam_first, dtype=float).reshape(-1, 4, 4).copy()
        m = len(self.q)
        self.active = np.ones(m, bool) if active is None else np.asarray(active, bool).copy()
        if self.active.shape != (m,):
            raise UsageError(f"active must have shape ({m},)")
        self.n_configs = m
        self.layout = ViewLayout(m, 1 + len(self.rigs0))
        self.n_views = self.layout.n_views
        self.k = len(self.free_idx)
        self.n_kin = self.k + len(self.offset_joints)  # the kinematic parameters (shared)
        act = np.flatnonzero(self.active)
        n = model.n
        n_rig = 6 * len(self.rigs0)
        self.n_dq = n * len(act) if joint_corrections else 0
        self.dq_cols = self.n_kin + n_rig + np.arange(self.n_dq)
        self.n_params = self.n_kin + n_rig + self.n_dq
        width = self.n_kin + (6 if n_rig else 0) + (n if joint_corrections else 0)
        cols = -np.ones((self.n_views, width), dtype=np.int64)
        by = self.layout.by_frame(cols)
        by[act, :, : self.n_kin] = np.arange(self.n_kin)
        for c in range(1, self.layout.n_cameras):
            by[act, c, self.n_kin : self.n_kin + 6] = self._rig_cols(c)
        if joint_corrections:
            dq = self.dq_cols.reshape(len(act), 1, n)
            by[act, :, width - n :] = dq
        self._cols = cols
        self._act = act

    def _rig_cols(self, c: int) -> np.ndarray:
        """Indices in ``p`` of camera ``c``'s (>= 1) rig parameters ``[w, v]``."""
        return self.n_kin + 6 * (c - 1) + np.arange(6)

    def initial_params(self) -> np.ndarray:
        return np.concatenate(
            [
                self.model.params.reshape(-1)[self.free_idx],
                np.zeros(len(self.offset_joints) + 6 * len(self.rigs0) + self.n_dq),
            ]
        )

    def joints(self, p: np.ndarray) -> np.ndarray:
        """Joint vectors (m_active, n) used for the active configurations (read-back + dq)."""
        q = self.q[self._act]
        if self.n_dq:
            q = q + p[self.dq_cols].reshape(q.shape)
        return q

    def view_columns(self) -> np.ndarray:
        return self._cols

    def param_instances(self) -> np.ndarray:
        """(n_params,) the configuration of each joint correction ``dq``, -1 for the kinematic
        and rig parameters (shared by all views)."""
        inst = -np.ones(self.n_params, np.int64)
        if self.n_dq:
            inst[self.dq_cols] = np.repeat(self._act, self.model.n)
        return inst

    def kinematic_model(self, p: np.ndarray) -> MCPCModel:
        """The MCPC model for parameters ``p``."""
        flat = self.model.params.reshape(-1).copy()
        flat[self.free_idx] = p[: self.k]
        if not len(self.offset_joints):
            return self.model.with_params(flat)
        offsets = np.asarray(self.model.joint_offsets, dtype=float).copy()
        offsets[self.offset_joints] += p[self.k : self.n_kin]
        return replace(self.model, params=flat.reshape(self.model.n + 1, 6), joint_offsets=offsets)

    def rig(self, p: np.ndarray, c: int = 1) -> np.ndarray:
        """``T_cam_first`` (4, 4) of camera ``c`` (default the second: ``T_right_left``)."""
        wv = p[self._rig_cols(c)]
        rig0 = self.rigs0[c - 1]
        return make_pose(
            pose_from_vec(np.r_[wv[:3], 0, 0, 0])[:3, :3] @ rig0[:3, :3], rig0[:3, 3] + wv[3:]
        )

    def rigs(self, p: np.ndarray) -> np.ndarray:
        """``T_cam_first`` (N - 1, 4, 4) of every further camera."""
        rigs = [self.rig(p, c) for c in range(1, self.layout.n_cameras)]
        return np.stack(rigs) if rigs else np.zeros((0, 4, 4))

    def poses(self, p: np.ndarray) -> np.ndarray:
        T = np.full((self.n_views, 4, 4), np.nan)
        by = self.layout.by_frame(T)
        act = self._act
        TL = self._first_views(fk_tool(self.kinematic_model(p), self.joints(p)))
        by[act, 0] = TL
        for c in range(1, self.layout.n_cameras):
            by[act, c] = self.rig(p, c) @ TL
        return T

    def _first_views(self, T_tool: np.ndarray) -> np.ndarray:
        """The first camera's view poses ``T_cam_world`` of the chain's tool poses (class
        docstring): their inverse, or eye-to-hand themselves."""
        return T_tool.copy() if self.eye_to_hand else inv_pose(T_tool)

    def view_jacobian(self, p: np.ndarray) -> np.ndarray:
        width = self._cols.shape[1]
        J = np.zeros((self.n_views, 6, width))
        by = self.layout.by_frame(J)
        act = self._act
        mdl = self.kinematic_model(p)
        qa = self.joints(p)
        JL = np.zeros((len(act), 6, width))
        JL[..., : self.k] = identification_jacobian(mdl, qa)[:, :, self.free_idx]
        if self.n_dq or len(self.offset_joints):
            tw = joint_twists(mdl, qa)
            JL[..., self.k : self.n_kin] = tw[:, :, self.offset_joints]
            if self.n_dq:
                JL[..., width - mdl.n :] = tw
        # the tool's body twist as the first camera's view twist (class docstring)
        JL = adjoint(fk_tool(mdl, qa)) @ JL if self.eye_to_hand else -JL
        by[act, 0] = JL
        for c in range(1, self.layout.n_cameras):
            Trig = self.rig(p, c)
            Jl = so3_left_jacobian(p[self._rig_cols(c)][:3])
            Jr = np.zeros((6, 6))
            Jr[:3, :3] = skew(Trig[:3, 3]) @ Jl
            Jr[:3, 3:] = np.eye(3)
            Jr[3:, :3] = Jl
            by[act, c] = adjoint(Trig) @ JL
            by[act, c, :, self.n_kin : self.n_kin + 6] = Jr
        return J


def joint_twists(model: MCPCModel, q: np.ndarray) -> np.ndarray:
    """(m, 6, n) the twist ``[v; w]`` of every joint's axis in the tool frame at the joints ``q``
    (m, n) rad / m: the derivative of the tool pose (body twist, rows as
    :func:`selfcal.kinematics.forward.identification_jacobian`) by each joint variable -- and by a
    revolute joint's zero offset."""
    F = fk_frames(model, q)
    X = inv_pose(F[:, -1:]) @ F[:, :-1]  # joint frames in the tool frame (m, n, 4, 4)
    w = X[..., :3, 2]
    tw = np.concatenate([np.cross(X[..., :3, 3], w), w], axis=-1)  # revolute
    pris = np.array([t == "prismatic" for t in model.joint_types])
    tw[:, pris] = np.concatenate([w[:, pris], 0 * w[:, pris]], axis=-1)
    return np.swapaxes(tw, 1, 2)
