"""The :class:`selfcal.calibration.field.bounds.FisherSetup` of a data set: predicted before it is taken (planning,
simulation) or taken from a calibration (the bounds of ``calibration.json``).

Both give the corners seen in each view (views: :class:`selfcal.estimation.observations.ViewLayout` over the
setup's configurations; ``pidx`` into the points, by the target's feature mapping), the points, the
scale markers' corners and the noise levels; :func:`selfcal.calibration.field.bounds.cramer_rao` turns a setup into
bounds. SI units, px.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.field.bounds import BoundsError, FisherSetup
from selfcal.calibration.field.joint_refine import encoder_sigma
from selfcal.camera import Cameras, CameraSet, Rig, Visibility
from selfcal.errors import InputError
from selfcal.estimation.observations import ViewLayout, views_per_point
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.target import CORNERS_PER_MARKER, marker_features

__all__ = ["predicted_setup", "setup_from_output"]


def predicted_setup(
    model: MCPCModel,
    q: np.ndarray,
    rig: Rig,
    marker_ids: np.ndarray,
    corners_world: np.ndarray,
    normals_world: np.ndarray,
    scale_ids: tuple[int, int],
    scale_distance_m: float,
    *,
    pixel_sigma_px: float,
    joint_sigma: np.ndarray | None = None,
    ref_config: int = 0,
    visibility: Visibility | None = None,
) -> FisherSetup:
    """The setup of a data set *before* it is taken: the corners (K markers, (K, 4, 3) m,
    normals (K, 3)) predicted to be seen by the cameras of ``rig`` (the model's tool is
    its first camera) at joints ``q`` (``visibility`` default: as the analytic simulator decides
    it, :class:`selfcal.camera.Visibility`). Points seen in fewer than two views are dropped (they
    carry no information).

    Raises:
        BoundsError: a scale marker is not seen twice.

    Cameras of the rig with different models become a :class:`selfcal.camera.CameraSet` (each
    camera's free parameters unknowns of their own), as the self-calibration estimates them.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    ids = np.asarray(marker_ids, dtype=np.int64)
    camera: Cameras = rig.cameras[0]
    if any(c != camera for c in rig.cameras[1:]):
        camera = CameraSet(rig.cameras, rig.names)
    rule = visibility or Visibility()
    vis = rig.visible_markers(rule, fk_tool(model, q), corners_world, normals_world)  # (m, N, K)
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
    # point index: the target's feature mapping over the kept markers' positions in the list
    view = np.repeat(ViewLayout(len(q), rig.n_cameras).view(cfg, cam), CORNERS_PER_MARKER)
    pidx = marker_features(remap[mk]).ravel()
    X = corners_world[kept].reshape(-1, 3)
    sa, sb = (marker_features(remap[np.flatnonzero(ids == sid)[0]]) for sid in scale_ids)
    return FisherSetup(
        model=model,
        q=q,
        camera=camera,
        T_first_cam=rig.T_first_cam,
        X_world=X,
        view=view,
        pidx=pidx,
        scale_points=(sa, sb),
        scale_distance_m=float(scale_distance_m),
        pixel_sigma_px=float(pixel_sigma_px),
        joint_sigma=None if joint_sigma is None else np.asarray(joint_sigma, dtype=float),
        ref_config=int(ref_config),
    )


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
    :class:`selfcal.calibration.field.calibrate.CalibrationOutput`, joint or two-stage): its model, camera, rig
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
        model, camera = res.model, res.camera if res.cameras is None else res.cameras
        T_first_cam, X, ref = res.T_first_cam, res.X_world, int(res.ref_config)
        held = tuple(n for n, why in res.held_reason.items() if not why.startswith("gauge"))
        sigma = res.sigma_px
    else:
        used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
        ident = out.identification
        model, camera = ident.model, sc.camera if sc.cameras is None else sc.cameras
        T_first_cam, X, ref = sc.T_first_cam, sc.X_world, int(sc.ref_config)
        held = tuple(ident.held)
        sigma = sc.pixel_sigma_px(len(used))
    if pixel_sigma_px is not None:
        sigma = float(pixel_sigma_px)
    if isinstance(joint_sigma, str):
        if joint_sigma != "encoder":
            raise InputError(
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
    view = ViewLayout(len(used), obs.n_cameras).view(pos[obs.config], obs.camera)
    # drop points seen in fewer than two views (no information), keep the scale markers
    nv = views_per_point(view[rows], pidx_all[rows], len(ids))
    pts = has_X & (nv >= 2)
    rows &= pts[pidx_all]
    remap = -np.ones(len(ids), np.int64)
    remap[pts] = np.arange(int(pts.sum()))
    scale = []
    for mk in ds_info.scale_ids:
        want = marker_features(int(mk))
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
        camera=camera,
        T_first_cam=np.asarray(T_first_cam, dtype=float),
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
