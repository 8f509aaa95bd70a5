"""The :class:`calib.bounds.FisherSetup` of a data set: predicted before it is taken (planning,
simulation) or taken from a calibration (the bounds of ``calibration.json``).

Both give the corners seen in each view (``view = 2 * config + camera``, ``pidx`` into the
points), the points, the scale markers' corners and the noise levels; :func:`calib.bounds.cramer_rao`
turns a setup into bounds. SI units, px.
"""

from __future__ import annotations

import numpy as np

from calib.bounds import BoundsError, FisherSetup
from calib.camera import Intrinsics
from calib.joint_refine import encoder_sigma
from calib.kinematics import fk_tool
from calib.mcpc import MCPCModel
from calib.transforms import inv_pose

__all__ = ["predicted_setup", "setup_from_output"]


def _visible_markers(
    T_world_cam: np.ndarray,
    intr: Intrinsics,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    margin_px: float,
    max_incidence_deg: float,
) -> np.ndarray:
    """(m, K) bool: all four corners in front and inside the image, face towards the camera."""
    T_cw = inv_pose(T_world_cam)
    Xc = np.einsum("mij,kcj->mkci", T_cw[:, :3, :3], corners_world) + T_cw[:, None, None, :3, 3]
    z = Xc[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intr.fx * Xc[..., 0] / z + intr.cx
        v = intr.fy * Xc[..., 1] / z + intr.cy
    ok = (z > 0.01) & (u > margin_px) & (u < intr.width - 1 - margin_px)
    ok &= (v > margin_px) & (v < intr.height - 1 - margin_px)
    ok = ok.all(axis=-1)
    to_cam = T_world_cam[:, None, :3, 3] - corners_world.mean(axis=1)[None]
    cosang = np.einsum("mkj,kj->mk", to_cam, normals_world) / np.linalg.norm(to_cam, axis=-1)
    return ok & (cosang > np.cos(np.radians(max_incidence_deg)))


def predicted_setup(
    model: MCPCModel,
    q: np.ndarray,
    T_left_right: np.ndarray,
    intr: Intrinsics,
    marker_ids: np.ndarray,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    scale_ids: tuple[int, int],
    scale_distance_m: float,
    *,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None = None,
    ref_config: int = 0,
    margin_px: float = 2.0,
    max_incidence_deg: float = 75.0,
) -> FisherSetup:
    """The setup of a data set *before* it is taken: the corners (K markers, (K, 4, 3) m,
    normals (K, 3)) predicted to be seen by the stereo pair at joints ``q`` (visibility as the
    analytic simulator decides it: all four corners inside the image with ``margin_px``, marker
    facing the camera within ``max_incidence_deg``). Points seen in fewer than two views are
    dropped (they carry no information).

    Raises:
        BoundsError: a scale marker is not seen twice.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    ids = np.asarray(marker_ids, dtype=np.int64)
    TL = fk_tool(model, q)
    TR = TL @ np.asarray(T_left_right, dtype=float)
    vis = np.stack(
        [
            _visible_markers(T, intr, corners_world, normals_world, margin_px, max_incidence_deg)
            for T in (TL, TR)
        ],
        axis=1,
    )  # (m, 2, K)
    n_views = vis.sum(axis=(0, 1))
    keep = n_views >= 2
    for sid in scale_ids:
        hit = np.flatnonzero(ids == sid)
        if hit.size == 0 or not keep[hit[0]]:
            raise BoundsError(f"scale marker {sid} is not seen in two views at these postures")
    kept = np.flatnonzero(keep)
    remap = -np.ones(len(ids), np.int64)
    remap[kept] = np.arange(len(kept))
    cfg, cam, mk = np.nonzero(vis & keep[None, None])
    view = np.repeat(2 * cfg + cam, 4)
    pidx = (4 * remap[mk][:, None] + np.arange(4)).ravel()
    X = corners_world[kept].reshape(-1, 3)
    sp = tuple(4 * remap[np.flatnonzero(ids == sid)[0]] + np.arange(4) for sid in scale_ids)
    return FisherSetup(
        model=model,
        q=q,
        T_left_right=np.asarray(T_left_right, dtype=float),
        fx=intr.fx,
        mu=intr.mu,
        cx=intr.cx,
        cy=intr.cy,
        X_world=X,
        view=view,
        pidx=pidx,
        scale_points=sp,
        scale_distance_m=float(scale_distance_m),
        pixel_sigma_px=float(pixel_sigma_px),
        joint_sigma=None if joint_sigma is None else np.asarray(joint_sigma, dtype=float),
        ref_config=int(ref_config),
    )


def _two_stage_sigma(sc, n_used: int) -> float:
    inl = np.asarray(sc.inlier, bool) & np.isfinite(sc.residuals).all(axis=1)
    has_X = np.isfinite(sc.X_world).all(axis=1)
    n_ba = 2 + 6 * (n_used - 1) + 5 + 3 * int(has_X.sum())
    dof = max(2 * int(inl.sum()) - n_ba, 1)
    return float(np.sqrt(np.sum(sc.residuals[inl] ** 2) / dof))


def setup_from_output(
    out,
    obs,
    q: np.ndarray,
    robot,
    ds_info,
    *,
    pixel_sigma_px: float | None = None,
    joint_sigma: np.ndarray | None | str = "encoder",
) -> FisherSetup:
    """The setup of a calibrated data set, evaluated at the final estimate of ``out`` (a
    :class:`calib.calibrate.CalibrationOutput`, joint or two-stage): its model, intrinsics, rig
    and points, the configurations the calibration used, the camera stage's inlier observations
    of reconstructed points, the reference configuration. ``obs``/``q`` as given to the
    calibration; ``ds_info`` for the scale markers and ``d``.

    ``pixel_sigma_px``: default the a-posteriori corner noise (joint: its residuals; two-stage:
    the bundle adjustment's, dof-corrected). ``joint_sigma``: ``"encoder"`` (default, the robot's
    encoder quantisation as the joint method models it), an (n,) array, or None (exact).
    """
    sc = out.selfcal
    res = getattr(out, "joint", None)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if res is not None:
        used = np.asarray(res.diagnostics.get("used_configs"), dtype=np.int64)
        model, fx, mu = res.model, res.fx, res.mu
        T_lr, X, ref = res.T_left_right, res.X_world, int(res.ref_config)
        held = tuple(n for n, why in res.held_reason.items() if not why.startswith("gauge"))
        sigma = res.sigma_px
    else:
        used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
        ident = out.identification
        model, fx, mu = ident.model, sc.fx, sc.mu
        T_lr, X, ref = sc.T_left_right, sc.X_world, int(sc.ref_config)
        held = tuple(ident.held)
        sigma = _two_stage_sigma(sc, len(used))
    if pixel_sigma_px is not None:
        sigma = float(pixel_sigma_px)
    if isinstance(joint_sigma, str):
        if joint_sigma != "encoder":
            raise ValueError(
                f"joint_sigma must be 'encoder', an array or None, not {joint_sigma!r}"
            )
        joint_sigma = encoder_sigma(robot)
    ids, pidx_all = obs.point_index()
    X = np.asarray(X, dtype=float)
    if len(X) != len(ids):
        raise BoundsError("the observations and the calibration disagree on the points")
    pos = -np.ones(obs.n_configs, np.int64)
    pos[used] = np.arange(len(used))
    has_X = np.isfinite(X).all(axis=1)
    rows = (pos[obs.config] >= 0) & has_X[pidx_all] & np.asarray(sc.inlier, bool)
    view = 2 * pos[obs.config] + obs.camera
    # drop points seen in fewer than two views (no information), keep the scale markers
    nv = np.zeros(len(ids), int)
    key = np.unique(pidx_all[rows] * (2 * len(used)) + view[rows])
    np.add.at(nv, key // (2 * len(used)), 1)
    pts = has_X & (nv >= 2)
    rows &= pts[pidx_all]
    remap = -np.ones(len(ids), np.int64)
    remap[pts] = np.arange(int(pts.sum()))
    scale = []
    for mk in ds_info.scale_ids:
        want = 4 * int(mk) + np.arange(4)
        at = np.searchsorted(ids, want)
        if not (np.all(at < len(ids)) and np.array_equal(ids[np.minimum(at, len(ids) - 1)], want)):
            raise BoundsError(f"scale marker {mk} is not observed")
        if not pts[at].all():
            raise BoundsError(f"scale marker {mk} is not reconstructed from two views")
        scale.append(remap[at])
    if pos[ref] < 0:
        raise BoundsError(f"the reference configuration {ref} is not among the used ones")
    return FisherSetup(
        model=model,
        q=q[used],
        T_left_right=np.asarray(T_lr, dtype=float),
        fx=float(fx),
        mu=float(mu),
        cx=float(sc.cx),
        cy=float(sc.cy),
        X_world=X[pts],
        view=view[rows],
        pidx=remap[pidx_all[rows]],
        scale_points=(scale[0], scale[1]),
        scale_distance_m=float(ds_info.scale_length_m),
        pixel_sigma_px=float(sigma),
        joint_sigma=None if joint_sigma is None else np.asarray(joint_sigma, dtype=float),
        held=held,
        ref_config=int(pos[ref]),
    )
