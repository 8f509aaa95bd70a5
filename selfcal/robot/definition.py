"""Robot definitions: the nominal kinematics of a robot, read from its one data file.

Each robot is a TOML file ``models/<folder>/<name>.toml`` holding its kinematics -- a standard DH
table (``convention = "dh"``, the default), a modified-DH table (``convention = "mdh"``, Craig) or a
``[urdf]`` table naming a URDF file and its base and tool links -- plus joint ranges, a home posture,
encoder resolution and the wrist-camera mount (mm, deg at that edge). A URDF file can also be
loaded directly (:mod:`selfcal.robot.urdf`). This module converts everything to SI (m, rad) on load
and to the convention-free chain ``G_0 Q_1 G_1 ... Q_n G_n`` of :mod:`selfcal.robot.chain`; nothing
else reads those files.
"""

from __future__ import annotations

import importlib.resources
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from selfcal.errors import InputError, UsageError
from selfcal.robot.chain import DHParams, dh_chain
from selfcal.robot.encoder import EncoderSpec, encoder_spec
from selfcal.robot.tables import (
    TOP_KEYS,
    Kinematics,
    RobotDefinitionError,
    camera_mount,
    floats,
    known_keys,
    per_joint,
    table_kinematics,
    urdf_kinematics,
)
from selfcal.robot.urdf import urdf_chain, urdf_home
from selfcal.tomlfile import read_toml

__all__ = [
    "RobotDef",
    "DHParams",
    "SimulationGains",
    "MjcfSettings",
    "MJCF_SHAPES",
    "MJCF_FIELDS",
    "with_dh",
    "load_robot",
    "list_robots",
    "robot_files",
    "models_dir",
    "RobotDefinitionError",  # defined with the file parsing (selfcal.robot.tables); load_robot raises it
]

MIN_JOINTS, MAX_JOINTS = 1, 12
"""Joint counts a robot file may have."""


def models_dir() -> Path:
    """The robot models folder: ``selfcal/models`` inside an installed wheel (package data, found
    through :mod:`importlib.resources`; pyproject ``force-include``), else ``models/`` of the source
    checkout next to this package. Never the working directory."""
    packaged = Path(str(importlib.resources.files("selfcal"))) / "models"
    if (packaged / "targets").is_dir():
        return packaged
    return Path(__file__).resolve().parents[2] / "models"


TARGETS_FOLDER = "targets"
"""The folder of ``models/`` that holds target files; every other folder is one robot's."""


def robot_files() -> dict[str, Path]:
    """Every shipped robot file by name: ``models/<folder>/<name>.toml``, one folder per robot
    with its generated MJCF, scene, picture and README (MuJoCo Menagerie's layout; a folder may
    hold variants of one arm, e.g. the ER-4u's paper and vendor tables).

    Raises:
        RobotDefinitionError: two robot files of one name.
    """
    out: dict[str, Path] = {}
    for p in sorted(models_dir().glob("*/*.toml")):
        if p.parent.name == TARGETS_FOLDER:
            continue
        if p.stem in out:
            raise RobotDefinitionError(f"two robot files named {p.stem}: {out[p.stem]} and {p}",
                                       fix="rename one of them: a robot's name is its file stem")  # fmt: skip
        out[p.stem] = p
    return out


def list_robots() -> list[str]:
    """Names of the shipped robots (:func:`robot_files`)."""
    return sorted(robot_files())


DEFAULT_SPAN_DEG = 45.0
"""Planning half-window of a revolute joint whose robot file has no ``[planning] span_deg``."""
DEFAULT_SPAN_MM = 100.0
"""Planning half-window of a prismatic joint whose robot file has no ``[planning] span_deg``."""
DEFAULT_KP, DEFAULT_KV, DEFAULT_ARMATURE = 200.0, 20.0, 0.05
"""Simulation gains of a joint whose robot file has no ``[simulation]`` table (SI units)."""


@dataclass(frozen=True)
class SimulationGains:
    """Per-joint MuJoCo position-actuator gains and joint armature (robot file ``[simulation]``).

    Attributes:
        kp: (n,) stiffness, N m/rad (N/m for a prismatic joint).
        kv: (n,) damping, N m s/rad (N s/m).
        armature: (n,) reflected rotor inertia, kg m^2 (kg).
    """

    kp: np.ndarray
    kv: np.ndarray
    armature: np.ndarray


MJCF_SHAPES = ("capsules", "turret")
"""Link geometry of a generated MuJoCo model: simple capsules between the joint frames (any arm),
or the SCORBOT's hand-made layout (turret, beams, wrist, gripper)."""

MJCF_FIELDS = ("default", "home")
"""Where a generated scene's marker field lies (``[mjcf] field``, :class:`MjcfSettings`)."""


DEFAULT_PICTURE_VIEW = (0.3, 0.2, 0.2, 1.0, -60.0, -18.0)
"""Overview camera of a robot picture whose ``[mjcf]`` table has no ``picture_view``."""


@dataclass(frozen=True)
class MjcfSettings:
    """Where and how ``python -m selfcal.sim.build_models`` writes a robot's MuJoCo files (``[mjcf]``).

    Attributes:
        folder: ``models/<folder>/`` holds ``<name>.xml``.
        title: the robot's name in the scene file's comment.
        scene: this robot's folder also gets ``scene.xml`` (the robot over the default marker
            field) and the picture.
        picture: file name of the rendered picture in the folder, or None.
        shapes: link geometry, one of :data:`MJCF_SHAPES`.
        view: the picture's overview camera ``(lookat x, y, z (m), distance (m), azimuth (deg),
            elevation (deg))`` (key ``picture_view``).
        field: where the scene's marker field lies, one of :data:`MJCF_FIELDS`: ``"default"``
            (``selfcal.sim.markers.make_marker_field()``'s centre) or ``"home"`` (centred where the home
            camera's optical axis meets the table, as the scenarios place it).
    """

    folder: str
    title: str
    scene: bool = False
    picture: str | None = None
    shapes: str = "capsules"
    view: tuple[float, ...] = DEFAULT_PICTURE_VIEW
    field: str = "default"


def _mjcf(table: object, where: str, name: str) -> MjcfSettings | None:
    if table is None:
        return None
    if not isinstance(table, dict) or "folder" not in table:
        raise RobotDefinitionError(
            f"{where} needs the key 'folder'", fix=f'add folder = "<dir under models/>" to {where}'
        )
    shapes = table.get("shapes", "capsules")
    if shapes not in MJCF_SHAPES:
        raise RobotDefinitionError(
            f"{where}: shapes must be one of {MJCF_SHAPES}, got {shapes!r}",
            fix=f'set shapes = "capsules" in {where}',
        )
    picture = table.get("picture")
    try:
        view = tuple(float(v) for v in table.get("picture_view", DEFAULT_PICTURE_VIEW))
    except (TypeError, ValueError):
        view = ()
    if len(view) != 6 or not np.all(np.isfinite(view)):
        raise RobotDefinitionError(
            f"{where}: picture_view must be 6 numbers (lookat x, y, z m, distance m, azimuth deg, "
            f"elevation deg), got {table.get('picture_view')!r}"
        )
    field = table.get("field", "default")
    if field not in MJCF_FIELDS:
        raise RobotDefinitionError(
            f"{where}: field must be one of {MJCF_FIELDS}, got {field!r}",
            fix=f'set field = "home" in {where} to centre the marker field on the home view',
        )
    return MjcfSettings(
        folder=str(table["folder"]),
        title=str(table.get("title", name)),
        scene=bool(table.get("scene", False)),
        picture=None if picture is None else str(picture),
        shapes=str(shapes),
        view=view,
        field=str(field),
    )


@dataclass(frozen=True)
class RobotDef:
    """Nominal kinematics of a serial robot, SI units.

    Attributes:
        name: robot name (a robot TOML's name, else its file stem; a bare URDF's ``<robot name>``).
        joint_names: one name per joint.
        joint_types: ``"revolute"`` or ``"prismatic"`` per joint.
        chain: (n + 1, 4, 4) the fixed transforms ``G_0 .. G_n`` (m) of the nominal chain
            ``T_base_flange(q) = G_0 Q_1(q_1) G_1 ... Q_n(q_n) G_n``, ``Q_i = Rz(q_i)`` (revolute)
            or ``Tz(q_i)`` (prismatic); see :mod:`selfcal.robot.chain`.
        dh: the DH or modified-DH table the chain was built from (:class:`DHParams`, rad and m;
            ``offset`` is a revolute joint's zero offset or a prismatic joint's constant theta,
            key ``theta_deg``), or None for a robot from a URDF.
        limits: (n, 2) joint ranges (rad or m).
        home: (n,) home posture (rad or m).
        counts_per_unit: (n,) encoder counts per rad (or per m); used to quantise read-back.
        T_flange_cam: 4x4 pose of the left camera (OpenCV convention) in the flange frame (the
            chain's end: the last DH frame, Craig's frame n, or the URDF tool link).
        planning_span: (n,) half-width (rad or m) of the window around ``home`` in which the
            trajectory planner draws postures (``[planning] span_deg``: deg, or mm for a
            prismatic joint, like ``home_deg``).
        simulation: actuator gains and armature for the MuJoCo model (``[simulation]``).
        encoder: the controller's encoder table (``[encoder]``, :mod:`selfcal.robot.encoder`), or
            ``None`` for a robot without encoder data.
        mjcf: the generated MuJoCo files' settings (``[mjcf]``), or None when none are committed.
        planning_window: whether the robot file gives ``[planning] span_deg`` (a URDF never
            does): False when ``planning_span`` is the default window around ``home``.
        camera_mount_given: whether the robot file gives ``[camera_mount]`` (a URDF never
            does): False when ``T_flange_cam`` is the default, the camera at the flange.
    """

    name: str
    description: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    chain: np.ndarray
    dh: DHParams | None
    limits: np.ndarray
    home: np.ndarray
    counts_per_unit: np.ndarray
    T_flange_cam: np.ndarray
    planning_span: np.ndarray
    simulation: SimulationGains
    encoder: EncoderSpec | None = None
    mjcf: MjcfSettings | None = None
    planning_window: bool = False
    camera_mount_given: bool = False

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_types)

    @property
    def edge_unit(self) -> np.ndarray:
        """(n,) SI units per unit at the edges: rad per deg for a revolute joint, m per mm for a
        prismatic one (joint values on the command line and in robot files are deg and mm)."""
        return np.where(np.array([t == "revolute" for t in self.joint_types]), np.pi / 180, 1e-3)

    @property
    def convention(self) -> str:
        """How the kinematics were given: ``"dh"``, ``"mdh"`` or ``"urdf"``."""
        return "urdf" if self.dh is None else self.dh.convention

    def check_joints(self, q: np.ndarray) -> None:
        """Raise ``ValueError`` naming the first joint of ``q`` (rad, shape (..., n)) out of range."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[-1] != self.n:
            raise InputError(f"{self.name}: expected {self.n} joint values, got {q.shape[-1]}")
        for j in range(self.n):
            lo, hi = self.limits[j]
            bad = (q[..., j] < lo - 1e-12) | (q[..., j] > hi + 1e-12) | ~np.isfinite(q[..., j])
            if np.any(bad):
                val = q[..., j][bad].flat[0]
                scale = 180 / np.pi if self.joint_types[j] == "revolute" else 1000.0
                unit = "deg" if self.joint_types[j] == "revolute" else "mm"
                raise InputError(
                    f"joint {j + 1} ({self.joint_names[j]}) = {val * scale:.3f} {unit} is outside "
                    f"its range [{lo * scale:.2f}, {hi * scale:.2f}] {unit} for {self.name}"
                )


def _resolve(name_or_path: str | Path) -> Path:
    path = Path(name_or_path)
    if path.suffix not in (".toml", ".urdf"):
        found = robot_files().get(str(name_or_path))
        path = found if found is not None else Path(f"{name_or_path}.toml")
        if found is None:
            raise RobotDefinitionError(
                f"unknown robot model '{name_or_path}'; known models: {', '.join(list_robots())}",
                fix="give one of the known names, the path of a robot TOML file "
                "(models/<folder>/<name>.toml) or of a URDF file",
            )
    if not path.is_file():
        raise RobotDefinitionError(f"robot file not found: {path}")
    return path


def load_robot(name_or_path: str | Path) -> RobotDef:
    """Load a robot by name (``models/<folder>/<name>.toml``), from a robot TOML path, or from a URDF
    path.

    A URDF alone: the chain runs from the root link to the leaf link reached through the most
    moving joints (:mod:`selfcal.robot.urdf`; an ambiguous choice is an error asking for a robot TOML
    with ``[urdf] base_link`` and ``tool_link``), the name is the URDF's ``<robot name>`` (the file
    stem when it names none), home is joint value 0
    (or the middle of a range that excludes 0, :func:`selfcal.robot.urdf.urdf_home`), the camera sits
    at the flange (the tool link) looking along its z axis, and the tables a robot TOML may add
    (encoder, planning, simulation, MJCF) take their defaults. A robot TOML without
    ``[camera_mount]`` (a robot measured by a tracker only) also has its camera at the flange.

    Raises:
        RobotDefinitionError: unknown name (the message lists the known ones) or malformed file
            (the message names the file and the key).
        selfcal.robot.urdf.UrdfError: a URDF without the named links, with a floating, planar or
            mimic joint in the chain, or otherwise unusable (an :class:`InputError` too).
    """
    path = _resolve(name_or_path)
    if path.suffix == ".urdf":
        return _from_urdf_file(path)
    data = read_toml(path, RobotDefinitionError)
    known_keys(data, TOP_KEYS, str(path), path)
    if "urdf" in data:
        kin = urdf_kinematics(data["urdf"], path)
        if "home_deg" not in data:  # as for a bare URDF: 0, or mid-range where 0 is outside
            data = {**data, "home_deg": list(urdf_home(kin.types, kin.limits))}
    else:
        kin = table_kinematics(data, path)
    mount = data.get("camera_mount")
    if mount is None:  # no camera (e.g. tracker measurements): at the flange, like a bare URDF
        return _assemble(path, data, kin, np.eye(4))
    if not isinstance(mount, dict):
        raise RobotDefinitionError(
            f"{path}: camera_mount must be a table",
            fix=f"write [camera_mount] with xyz_mm, x_axis and z_axis in {path}, or leave it out "
            "for a camera at the flange looking along its z axis",
        )
    return _assemble(path, data, kin, camera_mount(mount, f"{path}: [camera_mount]"))


def _from_urdf_file(path: Path) -> RobotDef:
    """A robot straight from a URDF file, with the defaults :func:`load_robot` describes."""
    ch = urdf_chain(path)
    kin = Kinematics(ch.joint_names, ch.joint_types, ch.limits, ch.chain, None)
    data = {"name": ch.name.strip() or path.stem, "description": f"{ch.name} (URDF {path.name}, {ch.base_link} -> "
            f"{ch.tool_link})", "home_deg": list(urdf_home(ch.joint_types, ch.limits))}  # fmt: skip
    return _assemble(path, data, kin, np.eye(4))


def _assemble(path: Path, data: dict, kin: Kinematics, T_flange_cam: np.ndarray) -> RobotDef:
    """The :class:`RobotDef` from the kinematics and the file's other tables (home, encoder,
    planning, simulation)."""
    types = kin.types
    n = len(types)
    if not MIN_JOINTS <= n <= MAX_JOINTS:
        raise RobotDefinitionError(
            f"{path}: {n} joints; a robot needs {MIN_JOINTS} to {MAX_JOINTS}",
            fix=f"describe a serial arm of {MIN_JOINTS} to {MAX_JOINTS} moving joints in {path}",
        )
    unit_vec = np.array([np.pi / 180 if t == "revolute" else 1e-3 for t in types])
    home = floats(data.get("home_deg", [0.0] * n))
    if home is None or home.shape != (n,) or not np.all(np.isfinite(home)):
        raise RobotDefinitionError(f"{path}: home_deg must have {n} finite values")
    if not isinstance(data.get("encoder", {}), dict):
        raise RobotDefinitionError(f"{path}: encoder must be a table [encoder]")
    cpd = floats(data.get("encoder", {}).get("counts_per_deg", [np.inf] * n))
    # inf: no quantisation; NaN refused
    if cpd is None or cpd.shape != (n,) or not np.all(cpd > 0):
        raise RobotDefinitionError(f"{path}: encoder.counts_per_deg must be {n} positive numbers")
    try:
        encoder = encoder_spec(data.get("encoder", {}), cpd / unit_vec, home * unit_vec, unit_vec)
    except InputError as exc:
        raise RobotDefinitionError(f"{path}: [encoder] {exc.message}", fix=exc.fix) from None
    revolute = np.array([t == "revolute" for t in types])
    planning_span = per_joint(
        data.get("planning", {}),
        "span_deg",
        n,
        f"{path}: [planning]",
        default=np.where(revolute, DEFAULT_SPAN_DEG, DEFAULT_SPAN_MM),
    )
    sim = data.get("simulation", {})
    where_sim = f"{path}: [simulation]"
    gains = SimulationGains(
        kp=per_joint(sim, "kp", n, where_sim, default=np.full(n, DEFAULT_KP)),
        kv=per_joint(sim, "kv", n, where_sim, default=np.full(n, DEFAULT_KV)),
        armature=per_joint(sim, "armature", n, where_sim, default=np.full(n, DEFAULT_ARMATURE)),
    )
    robot = RobotDef(
        name=str(data.get("name", path.stem)),
        description=str(data.get("description", "")),
        joint_names=kin.names,
        joint_types=types,
        chain=kin.chain,
        dh=kin.dh,
        limits=kin.limits,
        home=home * unit_vec,
        counts_per_unit=cpd / unit_vec,
        T_flange_cam=T_flange_cam,
        planning_span=planning_span * unit_vec,
        simulation=gains,
        encoder=encoder,
        mjcf=_mjcf(data.get("mjcf"), f"{path}: [mjcf]", str(data.get("name", path.stem))),
        planning_window="span_deg" in data.get("planning", {}),
        camera_mount_given="camera_mount" in data,
    )
    try:
        robot.check_joints(robot.home)
    except ValueError as exc:
        raise RobotDefinitionError(f"{path}: home posture: {exc}") from exc
    return robot


def with_dh(robot: RobotDef, dh: DHParams) -> RobotDef:
    """A copy of ``robot`` whose nominal chain is the table ``dh`` (e.g. a perturbed table)."""
    if dh.n != robot.n:
        raise UsageError(f"{robot.name} has {robot.n} joints, the table {dh.n} rows")
    return replace(robot, dh=dh, chain=dh_chain(dh))
