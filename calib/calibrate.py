"""Dataset -> calibration: detection, camera self-calibration, scale and sign, identification.

This is the paper's pipeline end to end (sections II-III). It reads only the dataset folder
(images or detections, joint read-back, the target description with the known distance d) and
never ``truth.json``. Output: a plain dict written as ``calibration.json`` (mm/deg for people,
plus the full SI model so it can be loaded back with :func:`model_from_calibration`).
"""

from __future__ import annotations

import os
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.bounds import BoundsError, bounds_block
from calib.detect import detect_markers
from calib.errors import EstimationError, InputError, SelfCalWarning
from calib.identify import IdentificationResult, identify, to_dh
from calib.io.dataset import Dataset, DatasetError, Detections, read_gray
from calib.joint_refine import method_summary, refine_calibration
from calib.kinematics import fk_tool
from calib.mcpc import (
    MCPCModel,
    dh_to_mcpc,
    minimal_indices,
    param_is_angle,
    param_names,
    shape_matrices,
)
from calib.robot_def import RobotDef, load_robot
from calib.selfcal import Observations, SelfCalibrationResult, self_calibrate
from calib.trajectory import check_not_degenerate
from calib.transforms import inv_pose, rot_z

__all__ = [
    "CalibrationError",
    "CalibrationFileError",
    "NoMarkersWarning",
    "detect_dataset",
    "calibrate",
    "CalibrationOutput",
    "model_from_calibration",
    "FORMAT",
    "METHODS",
]

FORMAT = "scorbot-selfcal-calibration"
MIN_POSTURES = 6


class CalibrationError(EstimationError, ValueError):
    """The dataset cannot be calibrated; the message names the cause and the fix. (Still a
    ``ValueError``, as it always was.)"""


class CalibrationFileError(InputError, CalibrationError):
    """A ``calibration.json`` that is not one or is damaged (bad input, exit code 2); still a
    :class:`CalibrationError` for callers that catch that."""


class NoMarkersWarning(SelfCalWarning):
    """Some images show no marker at all (they are skipped)."""


def detect_dataset(ds: Dataset, progress=None) -> Detections:
    """Marker corners of every image (images path) or the stored detections (analytic path)."""
    if ds.info.observation == "detections":
        return ds.read_detections()
    out: Detections = {}
    empty: list[str] = []
    if progress is not None:
        progress.start(2 * len(ds.indices))
    W, H = ds.info.resolution

    def detect(item: tuple[int, str, Path]) -> tuple[int, str, dict]:
        index, cam, path = item
        img = read_gray(path, index)
        if img.shape[1] != W or img.shape[0] != H:
            raise DatasetError(
                f"frame {index:04d}_{cam}.png is {img.shape[1]}x{img.shape[0]} px but dataset.json "
                f"says {W}x{H}"
            )
        return index, cam, detect_markers(img, dictionary=ds.info.dictionary)

    # OpenCV releases the GIL while decoding and detecting: use every core, keep the order.
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        for index, cam, dets in pool.map(detect, ds.image_paths()):
            if dets:
                out[(index, cam)] = dets
            else:
                empty.append(f"{index:04d}_{cam}")
            if progress is not None:
                progress.advance()
    if progress is not None:
        progress.finish()
    if empty:
        warnings.warn(
            f"{len(empty)} image(s) show no {ds.info.dictionary} marker and are skipped: "
            f"{', '.join(empty[:8])}{' ...' if len(empty) > 8 else ''}",
            NoMarkersWarning,
            stacklevel=2,
        )
    if not out:
        raise CalibrationError(
            f"no marker was detected in any image of {ds.root}; check the target dictionary "
            f"({ds.info.dictionary}), the lighting and that the camera sees the marker field"
        )
    return out


@dataclass
class CalibrationOutput:
    """What :func:`calibrate` produced: the JSON document and the live objects behind it."""

    document: dict
    selfcal: SelfCalibrationResult
    identification: IdentificationResult
    model: MCPCModel
    frames_used: np.ndarray
    joint: object | None = None
    """The :class:`calib.joint_refine.JointRefinementResult` when ``method="joint"``."""


def _observations(ds: Dataset, dets: Detections) -> Observations:
    pos = {int(i): k for k, i in enumerate(ds.indices)}
    remapped = {(pos[i], cam): m for (i, cam), m in dets.items() if i in pos}
    return Observations.from_corners(remapped, n_configs=len(ds.indices))


def _check_scale_markers(ds: Dataset, dets: Detections) -> None:
    for mid in ds.info.scale_ids:
        views = [k for k, m in dets.items() if mid in m]
        if len(views) < 2:
            raise CalibrationError(
                f"scale marker {mid} is seen in {len(views)} image(s); it must be seen in at least "
                "two so its position can be triangulated: move the scale bar into view or add "
                "postures that see it"
            )


def _mat(T: np.ndarray, digits: int = 9) -> list:
    return np.round(np.asarray(T, dtype=float), digits).tolist()


METHODS = ("two-stage", "joint")


def calibrate(root: str | Path, *, progress=None, method: str = "joint") -> CalibrationOutput:
    """Run the whole calibration on the dataset in ``root`` (see the module docstring).

    ``method``: ``"two-stage"`` (the paper: camera poses by bundle adjustment, then the
    kinematics fitted to the poses) or ``"joint"`` (default: the two-stage result refined by the
    one-step maximum-likelihood adjustment of :mod:`calib.joint_refine`). The document holds the
    final method's result under the usual keys, ``method``, and a summary of every method run
    under ``methods``.

    Raises:
        ValueError: unknown ``method``.
        DatasetError: missing or damaged dataset files.
        CalibrationError / calib.selfcal.SelfCalibrationError / calib.identify.IdentificationError:
            data that cannot determine the answer (each message names the cause).
    """
    if method not in METHODS:
        raise ValueError(f"unknown calibration method {method!r}; use one of {METHODS}")
    ds = Dataset.open(root)
    robot = load_robot(ds.info.robot_model)
    if len(ds.indices) < MIN_POSTURES:
        raise CalibrationError(
            f"{root}: {len(ds.indices)} postures; calibration needs at least {MIN_POSTURES} "
            "(26 kinematic parameters from 6 pose values each, plus the camera's unknowns): "
            "acquire more"
        )
    dets = detect_dataset(ds, progress=progress)
    _check_scale_markers(ds, dets)
    obs = _observations(ds, dets)
    q = np.radians(ds.joints_deg)
    nominal = dh_to_mcpc(robot).with_tool(robot.T_flange_cam)
    T_nom = fk_tool(nominal, q)
    check_not_degenerate(T_nom)
    W, H = ds.info.resolution
    sc = self_calibrate(
        obs,
        W,
        H,
        scale_markers=tuple(ds.info.scale_ids),
        scale_distance_m=ds.info.scale_length_m,
        nominal_cam_positions=T_nom[:, :3, 3],
        # The reconstruction frame becomes the world of the kinematic model: take a camera whose
        # x-axis is far from parallel to joint 1's axis (MCPC's base parameters are singular there).
        ref_scores=np.abs(T_nom[:, :3, 0] @ _joint1_axis(nominal)),
    )
    used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
    if len(used) < MIN_POSTURES:
        raise CalibrationError(
            f"only {len(used)} postures could be registered by the camera stage; calibration "
            f"needs at least {MIN_POSTURES}: acquire more postures that see the markers"
        )
    ident = identify(nominal, q[used], sc.T_world_cam[used, 0])
    doc = _document(ds, robot, sc, ident, used)
    out = CalibrationOutput(doc, sc, ident, ident.model, ds.indices[used])
    if method == "joint":
        out = refine_calibration(out, obs, q, robot, ds.info)
    else:
        doc["method"] = "two-stage"
        doc["methods"] = {"two-stage": method_summary(doc)}

    try:
        out.document["bounds"] = bounds_block(
            out,
            np.radians(ds.info.validation_joints_deg),
            obs=obs,
            q=q,
            robot=robot,
            ds_info=ds.info,
        )
    except BoundsError as exc:
        out.document["bounds"] = {"error": str(exc)}
    return out


def _document(
    ds: Dataset,
    robot: RobotDef,
    sc: SelfCalibrationResult,
    ident: IdentificationResult,
    used: np.ndarray,
) -> dict:
    model = ident.model
    idx = minimal_indices(model.joint_types)
    ang = param_is_angle(idx)
    scale = np.where(ang, 180.0 / np.pi, 1000.0)
    params = []
    for name, k, a, s in zip(param_names(idx), idx, ang, scale):
        j = list(ident.names).index(name)
        params.append(
            {
                "name": name,
                "unit": "deg" if a else "mm",
                "estimate": float(model.params.reshape(-1)[k] * s),
                "std": float(ident.std[j] * s) if np.isfinite(ident.std[j]) else None,
                "held": name in ident.held,
            }
        )
    # Hand-eye: the identified last shape matrix relative to the nominal flange of joint n.
    nominal_flange = dh_to_mcpc(robot)
    V_last = _last_link_to_tool(model)
    T_flange_cam = inv_pose(_last_link_to_tool(nominal_flange)) @ V_last
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dh = to_dh(model, robot)
    dh_doc: dict | None
    if dh is None:
        dh_doc = None
        dh_reason = "; ".join(str(w.message) for w in caught) or "not representable"
    else:
        dh_doc = {
            "rows": [
                {
                    "theta_offset_deg": np.degrees(o),
                    "d_mm": d * 1000,
                    "a_mm": a * 1000,
                    "alpha_deg": np.degrees(al),
                }
                for o, d, a, al in dh.rows()
            ],
        }
        dh_reason = None
    return {
        "format": FORMAT,
        "version": 1,
        "robot_model": robot.name,
        "dataset": {"frames": int(len(ds.indices)), "frames_used": int(len(used))},
        "world_frame": (
            "the left camera frame of frame camera_poses.reference_frame_index (the "
            "reconstruction frame); the identified base parameters place the robot in it"
        ),
        "intrinsics": {
            "fx": sc.fx,
            "fy": sc.fx * sc.mu,
            "mu": sc.mu,
            "cx": sc.cx,
            "cy": sc.cy,
            "width": sc.width,
            "height": sc.height,
            "fx_std": sc.fx_std,
            "mu_std": sc.mu_std,
        },
        "rig": {"T_left_right_m": _mat(sc.T_left_right)},
        "scale": {
            "d_mm": ds.info.scale_length_m * 1000,
            "d_hat": sc.d_hat,
            "k": sc.scale,
            "sign": sc.sign,
            "scale_marker_ids": list(ds.info.scale_ids),
        },
        "reprojection_rms_px": sc.rms_px,
        "observations": {"inliers": sc.n_inliers, "outliers": sc.n_outliers},
        "hand_eye": {"T_flange_cam_m": _mat(T_flange_cam)},
        "identification": identification_summary(ident),
        "parameters": params,
        "mcpc": {
            "joint_types": list(model.joint_types),
            "joint_offsets_rad": model.joint_offsets.tolist(),
            "params_si": model.params.tolist(),
            "columns": ["alpha", "beta", "gamma", "lx", "ly", "lz"],
            "tool": "left camera (OpenCV frame)",
        },
        "dh": dh_doc,
        "dh_note": dh_reason,
        "camera_poses": {
            "reference_frame_index": int(ds.indices[sc.ref_config]),
            "frame_index": [int(i) for i in ds.indices[used]],
            "T_world_cam_left_m": [_mat(T) for T in sc.T_world_cam[used, 0]],
        },
    }


def identification_summary(ident: IdentificationResult) -> dict:
    """The ``identification`` block of calibration.json (rank, conditioning, held parameters with
    their reasons, convergence, pose residuals before and after)."""
    return {
        "rank": int(ident.rank),
        "n_params": int(ident.n_params),
        "condition_number": float(ident.condition_number),
        "observability_o1": float(ident.o1),
        "observability_o3": float(ident.o3),
        "held": {n: ident.held_reason[n] for n in ident.held},
        "iterations": int(ident.iterations),
        "converged": bool(ident.converged),
        "pose_residual_rms": {
            "before": {"mm": ident.rms_t_mm_before, "deg": ident.rms_r_deg_before},
            "after": {"mm": ident.rms_t_mm_after, "deg": ident.rms_r_deg_after},
        },
    }


def _joint1_axis(model: MCPCModel) -> np.ndarray:
    """Joint 1's axis in the model's world frame (the z-axis of ``V_0``)."""
    return shape_matrices(model.params[0])[:3, 2]


def _last_link_to_tool(model: MCPCModel) -> np.ndarray:
    return rot_z(model.joint_offsets[-1]) @ shape_matrices(model.params[-1])


def model_from_calibration(doc: dict, where: str = "calibration.json") -> MCPCModel:
    """The identified MCPC model (tool = left camera, world = reconstruction frame) of a
    ``calibration.json`` document; raises CalibrationFileError naming what is missing or malformed."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        fmt = doc.get("format") if isinstance(doc, dict) else None
        raise CalibrationFileError(
            f"{where}: not a {FORMAT} document (format = {fmt!r})",
            fix="give the calibration.json that `selfcal calibrate DIR` wrote into DIR",
        )
    try:
        m = doc["mcpc"]
        types = tuple(m["joint_types"])
        params = np.asarray(m["params_si"], dtype=float)
        offsets = np.asarray(m["joint_offsets_rad"], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationFileError(
            f"{where}: missing or malformed 'mcpc' entry ({exc}); re-run `selfcal calibrate`"
        ) from None
    n = len(types)
    if (
        params.shape != (n + 1, 6)
        or offsets.shape != (n,)
        or not (np.isfinite(params).all() and np.isfinite(offsets).all())
    ):
        raise CalibrationFileError(
            f"{where}: mcpc.params_si must be {n + 1} x 6 finite numbers and joint_offsets_rad "
            f"{n}; got {params.shape} and {offsets.shape}: re-run `selfcal calibrate`"
        )
    return MCPCModel(params, types, offsets)
