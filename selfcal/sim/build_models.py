"""(Re)write the committed MJCF files of ``models/<folder>/`` from the robot TOML files.

Which robots get files, where, and which folder gets the scene is data: each robot file's
``[mjcf]`` table (``folder``, ``scene``, ``picture``, ``title``).

Run ``python -m selfcal.sim.build_models`` after changing ``models/*/*.toml``, ``selfcal/sim/robot_mjcf.py``
(or the modules it builds from: ``selfcal/sim/link_frames.py``, ``selfcal/sim/robot_shapes.py``,
``selfcal/sim/mjcf_geoms.py``), ``selfcal/sim/scene.py`` or ``selfcal/sim/markers.py``. It writes

- ``<name>.xml``: each robot alone, nominal (``robot_spec`` of
  ``nominal_mcpc(robot).with_tool(robot.T_flange_cam)``);
- ``scene.xml`` (the robot with ``scene = true``): includes its XML and adds table, lights and the
  default marker field (``make_marker_field()``; with ``field = "home"`` centred where the home
  camera looks, as the scenarios place it), whose textures are written to
  ``assets/aruco_<id>.png``;
- the ``picture``: the robot at ``home`` over the marker field, with both camera views.

The XML files are derived artefacts: ``tests/integration/test_mjcf.py`` regenerates them and compares. Every
pose that matters for kinematics or measurement (bodies, sites, cameras, named geoms such as the
marker tiles, joint ranges, keyframes) is written with full float64 precision (MuJoCo's own writer
keeps 6 significant digits), so the committed model reproduces the MCPC frames to 1e-15 m.
"""

from __future__ import annotations

import argparse
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import cv2
import mujoco
import numpy as np

from selfcal.errors import OutputError
from selfcal.kinematics.trajectory import home_target_center
from selfcal.robot.definition import (
    DEFAULT_PICTURE_VIEW,
    RobotDefinitionError,
    load_robot,
    models_dir,
    robot_files,
)
from selfcal.sim.link_frames import nominal_camera_model
from selfcal.sim.markers import MarkerField, make_marker_field, marker_texture_rgb
from selfcal.sim.robot_mjcf import RigConfig, robot_spec
from selfcal.sim.scene import PIXELS_PER_MODULE, scene_spec

__all__ = [
    "MjcfEntry",
    "mjcf_entries",
    "ROBOT_MODELS",
    "nominal_camera_model",
    "robot_xml",
    "scene_xml",
    "write_models",
    "render_picture",
    "main",
]


@dataclass(frozen=True)
class MjcfEntry:
    """A robot's generated MuJoCo files, from its robot file's ``[mjcf]`` table.

    ``folder``: ``models/<folder>/`` holds ``<name>.xml``; ``scene``: this robot's folder also gets
    ``scene.xml`` (the robot over the default marker field) and the picture ``picture``;
    ``title``: the robot's name in the scene file's comment.
    """

    name: str
    folder: Path
    scene: bool
    picture: str | None
    title: str
    view: tuple[float, ...] = DEFAULT_PICTURE_VIEW
    field: str = "default"

    def marker_field(self) -> MarkerField:
        """The scene's marker field: :func:`make_marker_field`'s default, or for ``field =
        "home"`` the same field centred where the home camera's optical axis meets the table
        (:func:`selfcal.kinematics.trajectory.home_target_center`, as the scenarios place it)."""
        if self.field == "default":
            return make_marker_field()
        robot = load_robot(self.name)
        return make_marker_field(center_xy_m=home_target_center(robot, nominal_camera_model(robot)))

    def field_note(self) -> str:
        """How the scene file's comment describes :meth:`marker_field`."""
        if self.field == "default":
            return "the default marker field (selfcal.sim.markers.make_marker_field())"
        return (
            "the default marker field centred where the home camera's optical axis meets the "
            "table (selfcal.kinematics.trajectory.home_target_center)"
        )


def mjcf_entries() -> list[MjcfEntry]:
    """Every robot in ``models/<folder>/`` whose file has an ``[mjcf]`` table (sorted by name), read
    through :func:`selfcal.robot.definition.load_robot` (``RobotDef.mjcf``)."""
    out = []
    for name, path in robot_files().items():
        m = load_robot(name).mjcf
        if m is None:
            continue
        if m.folder != path.parent.name:  # one folder per robot: its files beside its TOML
            raise RobotDefinitionError(
                f"{path}: [mjcf] folder = {m.folder!r}, but the file lives in "
                f"models/{path.parent.name}/",
                fix=f'set folder = "{path.parent.name}" or move the robot file into its folder',
            )
        out.append(MjcfEntry(name, path.parent, m.scene, m.picture, m.title, m.view, m.field))
    scenes = [e for e in out if e.scene]
    if len({e.folder for e in scenes}) != len(scenes):
        raise RobotDefinitionError(
            "two robots ask for scene.xml in the same folder: "
            + ", ".join(f"{e.name} -> {e.folder}" for e in scenes)
        )
    return out


ROBOT_MODELS = tuple(e.name for e in mjcf_entries())
"""Robots with committed MJCF files."""


def _fmt(x: float) -> str:
    """Shortest string that reads back as exactly ``x`` (``0`` for +-0)."""
    x = float(x)
    if x == 0.0:
        return "0"
    s = repr(x)
    return s[:-2] if s.endswith(".0") else s


def _fmt_vec(v) -> str:
    return " ".join(_fmt(x) for x in np.asarray(v, dtype=float).reshape(-1))


def precise_xml(spec: mujoco.MjSpec, xml: str) -> str:
    """Rewrite the kinematically relevant numbers of ``spec.to_xml()`` with full precision and
    return the re-indented XML text."""
    root = ET.fromstring(xml)
    by_tag = {
        "body": {b.name: b for b in spec.bodies if b.name},
        "site": {s.name: s for s in spec.sites if s.name},
        "camera": {c.name: c for c in spec.cameras if c.name},
        "geom": {g.name: g for g in spec.geoms if g.name},
    }
    for tag, elems in by_tag.items():
        for node in root.iter(tag):
            e = elems.get(node.get("name", ""))
            if e is None or node.get("fromto") is not None:
                continue
            pos, quat = np.asarray(e.pos, float), np.asarray(e.quat, float)
            if np.any(pos != 0) or "pos" in node.attrib:
                node.set("pos", _fmt_vec(pos))
            if np.any(quat != [1.0, 0.0, 0.0, 0.0]) or "quat" in node.attrib:
                node.set("quat", _fmt_vec(quat))
    joints = {j.name: j for j in spec.joints if j.name}
    for node in root.iter("joint"):
        j = joints.get(node.get("name", ""))
        if j is not None and "range" in node.attrib:
            node.set("range", _fmt_vec(j.range))
    acts = {a.name: a for a in spec.actuators if a.name}
    for tag in ("general", "position"):
        for node in root.iter(tag):
            a = acts.get(node.get("name", ""))
            if a is not None and "ctrlrange" in node.attrib:
                node.set("ctrlrange", _fmt_vec(a.ctrlrange))
    keys = {k.name: k for k in spec.keys if k.name}
    for node in root.iter("key"):
        k = keys.get(node.get("name", ""))
        if k is None:
            continue
        for attr in ("qpos", "ctrl"):
            if attr in node.attrib:
                node.set(attr, _fmt_vec(getattr(k, attr)))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def _header(text: str, comment: str) -> str:
    return f"<!-- {comment} -->\n{text}"


def _relative(path: Path) -> str:
    """``path`` below the models folder, as ``models/<folder>/<file>``."""
    return "models/" + path.relative_to(models_dir()).as_posix()


def robot_xml(name: str, rig: RigConfig | None = None) -> str:
    """MJCF text of robot ``name`` alone (nominal chain, stereo rig, actuators, ``home`` key)."""
    robot = load_robot(name)
    spec = robot_spec(robot, nominal_camera_model(robot), rig)
    spec.compile()  # validates; to_xml reflects the compiled spec
    text = precise_xml(spec, spec.to_xml())
    return _header(
        text,
        f"{robot.description}. GENERATED by `python -m selfcal.sim.build_models` from "
        f"{_relative(robot_files()[name])} (MCPC frames); do not edit.",
    )


def _marker_assets(field: MarkerField) -> dict[str, np.ndarray]:
    """Relative asset path -> RGB image of every marker texture of ``field``."""
    return {
        f"assets/aruco_{int(mid)}.png": marker_texture_rgb(
            field.dictionary, int(mid), PIXELS_PER_MODULE, field.quiet_zone_modules
        )
        for mid in field.ids
    }


def scene_xml(
    field: MarkerField,
    robot_file: str,
    asset_dir: Path,
    title: str = "",
    model_name: str = "scene",
    field_note: str = "the default marker field (selfcal.sim.markers.make_marker_field())",
) -> str:
    """MJCF text of the scene for ``field`` (described in the file's comment by ``field_note``)
    that includes ``robot_file``.

    The marker textures must already exist under ``asset_dir`` (the directory the scene file will
    live in) as returned by ``_marker_assets``; MuJoCo reads them while writing.
    """
    spec = scene_spec(field)
    spec.modelname = model_name
    spec.modelfiledir = str(asset_dir)
    for tex in spec.textures:
        if tex.name.startswith("aruco_tex_"):
            mid = int(tex.name.removeprefix("aruco_tex_"))
            tex.data = b""
            tex.width = tex.height = 0
            tex.file = f"assets/aruco_{mid}.png"
    spec.compile()
    text = precise_xml(spec, spec.to_xml())
    head, rest = text.split("\n", 1)
    text = f'{head}\n  <include file="{robot_file}"/>\n\n{rest}'
    return _header(
        text,
        f"{title or robot_file} scene: {robot_file} + table, lights and {field_note}. "
        "GENERATED by `python -m selfcal.sim.build_models`; do not edit.",
    )


def _folder(entry: MjcfEntry, out_dir: Path | None) -> Path:
    return (
        entry.folder if out_dir is None else Path(out_dir) / entry.folder.relative_to(models_dir())
    )


def write_models(out_dir: Path | None = None) -> list[Path]:
    """Write every robot's XML file (robots with an ``[mjcf]`` table), the marker textures and
    ``scene.xml`` into ``models/<folder>/`` (or ``out_dir/<folder>/``, for a check).

    Returns the paths written (the picture is separate: :func:`render_picture`).
    """
    written: list[Path] = []
    for e in mjcf_entries():
        folder = _folder(e, out_dir)
        folder.mkdir(parents=True, exist_ok=True)
        p = folder / f"{e.name}.xml"
        p.write_text(robot_xml(e.name))
        written.append(p)
        if not e.scene:
            continue
        field = e.marker_field()
        (folder / "assets").mkdir(parents=True, exist_ok=True)
        for rel, img in _marker_assets(field).items():
            p = folder / rel
            if not cv2.imwrite(str(p), np.ascontiguousarray(img[:, :, ::-1])):
                raise OutputError(f"could not write {p}")
            written.append(p)
        p = folder / "scene.xml"
        p.write_text(
            scene_xml(
                field,
                f"{e.name}.xml",
                folder,
                e.title,
                model_name=f"{e.folder.name} scene",
                field_note=e.field_note(),
            )
        )
        written.append(p)
    return written


def render_picture(
    scene_path: Path,
    out_path: Path,
    width: int = 960,
    height: int = 720,
    view: tuple[float, ...] = DEFAULT_PICTURE_VIEW,
) -> Path:
    """Render the robot of ``scene_path`` at its ``home`` keyframe over the marker field, with the
    left and right camera views underneath; writes a PNG to ``out_path``. ``view``: the overview
    camera (lookat x, y, z in m, distance m, azimuth and elevation deg; ``[mjcf] picture_view``)."""
    model = mujoco.MjModel.from_xml_path(str(scene_path))
    model.vis.global_.offwidth = max(width, int(model.vis.global_.offwidth))
    model.vis.global_.offheight = max(height, int(model.vis.global_.offheight))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    cam.lookat[:] = view[:3]
    cam.distance, cam.azimuth, cam.elevation = view[3:6]
    with mujoco.Renderer(model, height, width) as r:
        r.update_scene(data, cam)
        main_img = r.render().copy()
    views = []
    for name in ("cam_left", "cam_right"):
        cid = model.camera(name).id
        w, h = (int(v) for v in model.cam_resolution[cid])
        with mujoco.Renderer(model, h, w) as r:
            r.update_scene(data, name)
            views.append(r.render().copy())
    strip = np.concatenate(views, axis=1)
    sw = width
    sh = int(round(strip.shape[0] * sw / strip.shape[1]))
    strip = cv2.resize(strip, (sw, sh), interpolation=cv2.INTER_AREA)
    img = np.concatenate([main_img, np.full((4, width, 3), 255, np.uint8), strip], axis=0)
    for text, x in (("cam_left", 8), ("cam_right", sw // 2 + 8)):
        cv2.putText(
            img,
            text,
            (x, height + 26),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.7,
            (255, 255, 255),
            2,
            cv2.LINE_AA,
        )
    out_path = Path(out_path)
    if not cv2.imwrite(str(out_path), img[:, :, ::-1]):
        raise OutputError(f"could not write {out_path}")
    return out_path


def main(argv: list[str] | None = None) -> int:
    """CLI: ``python -m selfcal.sim.build_models [--out DIR] [--no-picture]``."""
    ap = argparse.ArgumentParser(
        prog="python -m selfcal.sim.build_models",  # not its file: sim imports no console
        description=__doc__.split("\n\n")[0],
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write into DIR/<folder>/ (default: models/<folder>/)",
    )
    ap.add_argument("--no-picture", action="store_true", help="skip rendering the pictures")
    args = ap.parse_args(argv)
    written = write_models(args.out)
    if not args.no_picture:
        for e in mjcf_entries():
            if e.scene and e.picture:
                folder = _folder(e, args.out)
                written.append(
                    render_picture(folder / "scene.xml", folder / e.picture, view=e.view)
                )
    for p in written:
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
