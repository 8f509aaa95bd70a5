"""The parameter table of a deployed model as TOML (mm / deg): :func:`to_toml` and :func:`from_toml`.

The table round-trips to the model (full float precision): ``[joints]``, one ``[[mcpc]]`` row per
shape matrix, the minimal parameters with nominal value, deviation and the calibration's std,
the tool camera, the base frame in the reconstruction frame, the camera and the DH table (or why
there is none). Frames and units: :mod:`selfcal.export.deploy`.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from selfcal.camera import Intrinsics
from selfcal.export.deploy import (
    BASE_FRAME,
    FIXED_BY_BASE_FRAME,
    TOOL_FRAME,
    DeployedModel,
    DeployError,
    as_rigid,
    nominal_deployed_params,
)
from selfcal.export.deploy import float_text as _f
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_is_angle, param_names
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.transforms import make_pose

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["DEPLOY_FORMAT", "to_toml", "from_toml"]

DEPLOY_FORMAT = "scorbot-selfcal-deployed"


def _arr(v) -> str:
    return "[" + ", ".join(_f(x) for x in np.asarray(v, dtype=float).reshape(-1)) + "]"


def _mat(R) -> str:
    return "[" + ", ".join(_arr(r) for r in np.asarray(R, dtype=float)) + "]"


def _s(text: str) -> str:
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"') + '"'


def _pose_lines(T: np.ndarray) -> list[str]:
    return [f"R = {_mat(T[:3, :3])}", f"xyz_mm = {_arr(T[:3, 3] * 1000.0)}"]


def to_toml(dep: DeployedModel, robot: RobotDef | None = None) -> str:
    """The parameter table of ``dep`` as TOML text (mm / deg), readable by :func:`from_toml`.

    Sections: ``[joints]`` (names, types, constant offsets, ranges, home), ``[[mcpc]]`` (one row
    per shape matrix ``V_i = Rx(alpha) Ry(beta) Rz(gamma) Trans(lx, ly, lz)``, i = 0..n, full
    precision: these define the model), ``[[parameters]]`` (the minimal identifiable set with the
    nominal value, the deviation and the calibration's std), ``[tool_camera]`` (left camera in the
    tool-tip frame), ``[base_in_reconstruction]``, ``[camera]`` (intrinsics, rig) and ``[dh]`` (the
    DH table in the robot's own convention, standard or modified DH, or a note why there is none).
    """
    robot = load_robot(dep.robot_name) if robot is None else robot
    m = dep.model
    n = m.n
    deg = 180.0 / math.pi
    unit = [deg, deg, deg, 1000.0, 1000.0, 1000.0]
    names_u = ["alpha_deg", "beta_deg", "gamma_deg", "lx_mm", "ly_mm", "lz_mm"]
    rev = [t == "revolute" for t in dep.joint_types]
    L = [
        f"# Calibrated kinematics of {dep.robot_name}, written by scorbot-selfcal (selfcal.export.deploy).",
        f"# Source: {dep.source or 'n/a'}",
        "# Units: mm and deg. Model: T_base_tip(q) = V_0 Q_1(q_1) V_1 ... Q_n(q_n) V_n with",
        "# V_i = Rx(alpha_i) Ry(beta_i) Rz(gamma_i) Trans(lx_i, ly_i, lz_i) and Q_k = Rz(q_k + offset_k)",
        "# (revolute) or Tz(q_k) (prismatic); q = the controller's joint readings.",
        f'format = "{DEPLOY_FORMAT}"',
        "version = 1",
        f"robot_model = {_s(dep.robot_name)}",
        f"source = {_s(dep.source)}",
        f"base_frame = {_s(BASE_FRAME)}",
        f"tool_frame = {_s(TOOL_FRAME)}",
        "",
        "[joints]",
        "names = [" + ", ".join(_s(x) for x in dep.joint_names) + "]",
        "types = [" + ", ".join(_s(x) for x in dep.joint_types) + "]",
        f"offset_deg = {_arr(m.joint_offsets * deg)}",
        *([f"base_offset_deg = {_f(m.base_offset * deg)}"] if m.base_offset else []),
        "# ranges and home: deg for revolute joints, mm for prismatic ones",
        "range = " + _mat([lim * (deg if r else 1000.0) for lim, r in zip(dep.limits, rev)]),
        f"home = {_arr([h * (deg if r else 1000.0) for h, r in zip(dep.home, rev)])}",
        "",
    ]
    for i in range(n + 1):
        L.append("[[mcpc]]")
        L.append(f"frame = {i}")
        L += [f"{nm} = {_f(m.params[i, c] * unit[c])}" for c, nm in enumerate(names_u)]
        L.append("")
    nominal = nominal_deployed_params(robot)
    idx = minimal_indices(m.joint_types)
    ang = param_is_angle(idx)
    L.append(
        "# The minimal identifiable set (Zhuang's eq. 10) in the base frame. std: one sigma of the "
        "same-named parameter as identified in the reconstruction frame (calibration.json), which "
        "carries over to first order. alpha0, beta0, lx0, ly0, beta1 are zero and ly1 = d1 "
        "sin(alpha1) with the nominal d1 by the choice of the base frame (fixed_by_base_frame)."
    )
    for name, k, a in zip(param_names(idx), idx, ang):
        s = deg if a else 1000.0
        v, v0 = m.params.reshape(-1)[k] * s, nominal.reshape(-1)[k] * s
        d = v - v0
        if a:
            d = (d + 180.0) % 360.0 - 180.0
        L += [
            "[[parameters]]",
            f"name = {_s(name)}",
            f'unit = "{"deg" if a else "mm"}"',
            f"value = {_f(v)}",
            f"nominal = {_f(v0)}",
            f"deviation = {_f(d)}",
        ]
        if name in FIXED_BY_BASE_FRAME:
            L.append("fixed_by_base_frame = true")
        elif name in dep.std:
            L.append(f"std = {_f(dep.std[name] * s)}")
        L.append("")
    L += ["[tool_camera]  # the left camera (OpenCV frame) in the tool-tip frame (rigid assembly)"]
    L += _pose_lines(dep.T_tip_cam) + [""]
    L += ["[base_in_reconstruction]  # the base frame in the calibration's world frame"]
    L += _pose_lines(dep.T_world_base) + [""]
    if dep.intrinsics is not None:
        cam = dep.intrinsics
        L += [
            "[camera]  # calibrated pinhole intrinsics (px, OpenCV), both cameras"
            if dep.intrinsics_right is None
            else "[camera]  # calibrated pinhole intrinsics (px, OpenCV), the left camera",
            *_pinhole_lines(cam),
            "",
        ]
        if dep.T_left_right is not None:
            L += ["[camera.T_left_right]  # right camera in the left camera's frame"]
            L += _pose_lines(dep.T_left_right) + [""]
        if dep.intrinsics_right is not None:
            L += ["[camera.right]  # the right camera's own intrinsics (px, OpenCV)"]
            L += _pinhole_lines(dep.intrinsics_right) + [""]
    dh, note = dep.dh(robot)
    if dh is None:
        L.append("[dh]  # the DH table in the robot's own convention (DH or modified DH)")
        L.append(f"note = {_s(f'no DH table: {note}')}")
        L.append("")
    elif dh.convention == "mdh":
        L.append(
            "[dh]  # modified DH (Craig), A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(q_i + "
            "theta_offset_i) Tz(d_i); row i holds alpha_{i-1} and a_{i-1}"
        )
        L.append('convention = "mdh"')
        L.append(
            "note = "
            + _s("T_world_base = frame 0 in the base frame; T_flange_tool = tool tip in frame n")
        )
    else:
        L.append("[dh]  # standard DH, A_i = Rz(q_i + theta_offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)")
        L.append('convention = "dh"')
        L.append("note = " + _s("DH frame 0 = the base frame; T_flange_tool = tool tip in frame n"))
    if dh is not None:
        rows = ", ".join(
            f"{{theta_offset_deg = {_f(o * deg)}, d_mm = {_f(d * 1000)}, a_mm = {_f(a * 1000)}, "
            f"alpha_deg = {_f(al * deg)}}}"
            for o, d, a, al in dh.rows()
        )
        L.append(f"rows = [{rows}]")
        L.append("")
        if dh.convention == "mdh":
            L.append("[dh.T_world_base]")
            L += _pose_lines(dh.T_world_base) + [""]
        L.append("[dh.T_flange_tool]")
        L += _pose_lines(dh.T_flange_tool) + [""]
    return "\n".join(L)


def _pinhole_lines(cam: Intrinsics) -> list[str]:
    """The pinhole keys of a ``[camera]`` table (px)."""
    return [f"fx = {_f(cam.fx)}", f"mu = {_f(cam.mu)}", f"cx = {_f(cam.cx)}",
            f"cy = {_f(cam.cy)}", f"width = {int(cam.width)}", f"height = {int(cam.height)}"]  # fmt: skip


def _pinhole_from(c: dict) -> Intrinsics:
    """The pinhole of a ``[camera]`` table (px)."""
    return Intrinsics(float(c["fx"]), float(c["mu"]), float(c["cx"]), float(c["cy"]),
                      int(c["width"]), int(c["height"]))  # fmt: skip


def _pose_from(t: dict, what: str) -> np.ndarray:
    try:
        return as_rigid(
            make_pose(np.asarray(t["R"], float), np.asarray(t["xyz_mm"], float) / 1000), what
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise DeployError(f"{what}: needs R (3x3) and xyz_mm (3): {exc}") from exc


def from_toml(text: str) -> DeployedModel:
    """Read a parameter table written by :func:`to_toml` back into a :class:`DeployedModel`.

    Raises:
        DeployError: not valid TOML, another format, or missing / malformed keys (named).
    """
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DeployError(f"not valid TOML: {exc}") from exc
    if d.get("format") != DEPLOY_FORMAT:
        raise DeployError(f"not a {DEPLOY_FORMAT} file (format = {d.get('format')!r})")
    deg = math.pi / 180.0
    try:
        j = d["joints"]
        types = tuple(j["types"])
        rev = np.array([t == "revolute" for t in types])
        to_si = np.where(rev, deg, 1e-3)
        n = len(types)
        rows = sorted(d["mcpc"], key=lambda r: r["frame"])
        if [r["frame"] for r in rows] != list(range(n + 1)):
            raise DeployError(f"[[mcpc]] must hold frames 0..{n} once each")
        scale = np.array([deg, deg, deg, 1e-3, 1e-3, 1e-3])
        cols = ["alpha_deg", "beta_deg", "gamma_deg", "lx_mm", "ly_mm", "lz_mm"]
        params = np.array([[float(r[c]) for c in cols] for r in rows]) * scale
        model = MCPCModel(params, types, np.asarray(j["offset_deg"], float) * deg,
                          float(j.get("base_offset_deg", 0.0)) * deg)  # fmt: skip
        std = {}
        for p in d.get("parameters", []):
            if "std" in p:
                std[p["name"]] = float(p["std"]) * (deg if p["unit"] == "deg" else 1e-3)
        intr, T_lr, intr_right = None, None, None
        if "camera" in d:
            c = d["camera"]
            intr = _pinhole_from(c)
            if "right" in c:
                intr_right = _pinhole_from(c["right"])
            if "T_left_right" in c:
                T_lr = _pose_from(c["T_left_right"], "[camera.T_left_right]")
        return DeployedModel(
            robot_name=str(d["robot_model"]),
            joint_names=tuple(j["names"]),
            joint_types=types,
            limits=np.asarray(j["range"], float) * to_si[:, None],
            home=np.asarray(j["home"], float) * to_si,
            model=model,
            T_tip_cam=_pose_from(d["tool_camera"], "[tool_camera]"),
            T_world_base=_pose_from(d["base_in_reconstruction"], "[base_in_reconstruction]"),
            std=std,
            intrinsics=intr,
            T_left_right=T_lr,
            source=str(d.get("source", "")),
            intrinsics_right=intr_right,
        )
    except KeyError as exc:
        raise DeployError(f"parameter file lacks key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, DeployError):
            raise
        raise DeployError(f"malformed parameter file: {exc}") from exc
