"""A URDF's serial chain from a base link to a tool link, as the fixed transforms of
:mod:`selfcal.robot.chain` (parsed with yourdfpy; meshes are not loaded).

Each moving joint ``k`` of the path has its origin ``O_k`` (parent link -> joint frame) and a unit
axis ``a_k`` in the joint frame; the child link is ``O_k Rot(a_k, q_k)``. With ``R_k`` the rotation
taking z onto ``a_k``, ``Rot(a_k, q) = R_k Rz(q) R_k^T``, so the chain's fixed transforms are
``G_0 = F_0 O_1 R_1``, ``G_k = R_k^T F_k O_{k+1} R_{k+1}`` and ``G_n = R_n^T F_n`` where ``F_k`` is
the product of the fixed joints between moving joints k and k + 1 (and after the last one, up to
the tool link). A prismatic joint slides along ``a_k`` the same way.

Choosing the links when a URDF is given without names (:func:`urdf_chain` with None): the base is
the URDF's root link; the tool is the leaf link reached through the most moving joints. When
several leaves tie (e.g. two gripper fingers) the call fails and asks for ``tool_link``.

Joints: ``revolute`` and ``prismatic`` (limits from ``<limit>``), ``continuous`` (revolute with
limits +-360 deg), ``fixed`` (folded into ``G``). A ``floating`` or ``planar`` joint, or a mimic
joint, in the chain is refused; so is a joint graph that is not a tree (a kinematic loop, a link
with two parents: before, the chain's walk never ended), naming the joint, and a file that is not
XML with a ``<robot>`` root (before yourdfpy logs its parser's complaints).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.errors import InputError
from selfcal.transforms import inv_pose, matrix_from_rotvec

__all__ = ["UrdfError", "UrdfChain", "urdf_chain", "urdf_home", "CONTINUOUS_LIMIT"]

CONTINUOUS_LIMIT = 2 * np.pi
"""Range (+-, rad) given to a URDF ``continuous`` joint."""


class UrdfError(InputError):
    """A URDF that does not describe a usable serial chain between the named links."""


@dataclass(frozen=True, eq=False)
class UrdfChain:
    """The moving joints between ``base_link`` and ``tool_link`` of a URDF (SI units).

    Attributes:
        name: the URDF's robot name.
        base_link, tool_link: the chain's ends (the chain's base and flange frames).
        joint_names, joint_types: per moving joint (``"revolute"`` or ``"prismatic"``).
        limits: (n, 2) joint ranges (rad or m).
        chain: (n + 1, 4, 4) the fixed transforms ``G_0 .. G_n`` (m).
    """

    name: str
    base_link: str
    tool_link: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    limits: np.ndarray
    chain: np.ndarray


def _z_onto(axis: np.ndarray) -> np.ndarray:
    """4x4 rotation taking the z axis onto the unit vector ``axis``."""
    z = np.array([0.0, 0.0, 1.0])
    c = np.cross(z, axis)
    s, cos = np.linalg.norm(c), float(z @ axis)
    T = np.eye(4)
    if s < 1e-15:
        if cos < 0:
            T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # Rx(pi)
        return T
    T[:3, :3] = matrix_from_rotvec(c / s * np.arctan2(s, cos))
    return T


def _check_xml(path: Path) -> None:
    """Refuse a file that is not XML with a ``<robot>`` root, before yourdfpy (which logs the
    XML parser's complaints and then fails with a TypeError's text)."""
    from xml.etree import ElementTree

    fix = f"give a URDF: XML with <robot>, <link> and <joint> ({path} is another kind of file)"
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as exc:
        raise UrdfError(f"{path}: not a URDF: not XML ({exc})", fix=fix) from None
    except OSError as exc:
        raise UrdfError(f"{path}: cannot be read ({exc.strerror or exc})", fix=fix) from None
    if root.tag != "robot":
        raise UrdfError(f"{path}: not a URDF: the root element is <{root.tag}>, not <robot>",
                        fix=fix)  # fmt: skip


def _check_tree(path: Path, joints: list) -> None:
    """Refuse a joint graph that is not a tree (a link with two parent joints, a closed loop),
    naming the joint; the chain walks below would not end."""
    parent_of: dict[str, Any] = {}
    fix = (
        "remove the joint that closes the loop (URDF describes open chains only; a parallel "
        "linkage is modelled by its serial chain)"
    )
    for j in joints:
        if j.child in parent_of:
            first = parent_of[j.child].name
            raise UrdfError(
                f"{path}: joint {j.name!r} makes link {j.child!r} the child of a second joint "
                f"({first!r} is the first): a kinematic loop or a link with two parents, and a "
                "URDF is a tree",
                fix=f"{fix}: {j.name!r}",
            )
        parent_of[j.child] = j
    order = {id(j): k for k, j in enumerate(joints)}
    for start in parent_of:
        seen: list[str] = []
        link = start
        while link in parent_of and link not in seen:
            seen.append(link)
            link = parent_of[link].parent
        if link in seen:
            loop = [parent_of[x] for x in seen[seen.index(link) :]]
            last = max(loop, key=lambda j: order[id(j)])
            raise UrdfError(
                f"{path}: joint {last.name!r} closes a kinematic loop (joints "
                f"{', '.join(repr(j.name) for j in loop)}): a URDF is a tree",
                fix=f"{fix}: {last.name!r}",
            )


def _load(path: Path):
    import logging

    import yourdfpy  # heavy (trimesh); only needed when a URDF is read

    _check_xml(path)
    log = logging.getLogger("yourdfpy")
    level = log.level
    log.setLevel(logging.CRITICAL)  # its parse errors become ours (one message), then restored
    try:
        # a non-finite <origin> or <axis> (nan, inf, 1e309) makes its transform non-finite in
        # the parser's trigonometry and products: refused below with the joint's name
        # (urdf_chain checks every number it takes), so numpy's "invalid value" is not the user's
        with np.errstate(invalid="ignore", over="ignore"):
            return yourdfpy.URDF.load(
                str(path),
                build_scene_graph=False,
                load_meshes=False,
                build_collision_scene_graph=False,
                load_collision_meshes=False,
            ).robot
    except Exception as exc:  # yourdfpy raises lxml, ValueError, ... on malformed files
        raise UrdfError(
            f"{path}: not a readable URDF ({type(exc).__name__}: {exc})",
            fix=f"check that {path} is a valid URDF (XML with <robot>, <link> and <joint>)",
        ) from exc
    finally:
        log.setLevel(level)


_NAME_LINKS = (
    "name the links: --base-link / --tool-link (selfcal import), or a robot TOML beside the URDF "
    'with [urdf] file = "ARM.urdf", base_link = "...", tool_link = "..." given as --robot'
)


def _default_base(path: Path, joints: list, links: list[str]) -> str:
    """The URDF's one root link (the default base link)."""
    children = {j.child for j in joints}
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise UrdfError(
            f"{path}: {len(roots)} root links ({', '.join(roots)}); cannot choose the base link",
            fix=_NAME_LINKS,
        )
    return roots[0]


def _default_tool(path: Path, joints: list, links: list[str], base_link: str) -> str:
    """The leaf link below ``base_link`` reached through the most moving joints (the default
    tool link); a tie (e.g. two gripper fingers) is an error naming the candidates."""
    parents = {j.parent for j in joints}
    by_child = {j.child: j for j in joints}
    depth = {}
    for leaf in (name for name in links if name not in parents):
        k, link = 0, leaf
        while link in by_child and link != base_link:
            k += by_child[link].type != "fixed"
            link = by_child[link].parent
        if link == base_link:
            depth[leaf] = k
    if not depth:
        raise UrdfError(f"{path}: no leaf link below link {base_link!r}", fix=_NAME_LINKS)
    best = max(depth.values())
    tools = sorted(name for name, k in depth.items() if k == best)
    if len(tools) != 1:
        raise UrdfError(
            f"{path}: the leaf links {', '.join(tools)} all end {best} moving joints below "
            f"{base_link!r}; cannot choose the tool link",
            fix=f"{_NAME_LINKS} (e.g. the flange or hand link the leaves hang from)",
        )
    return tools[0]


def urdf_chain(
    path: str | Path, *, base_link: str | None = None, tool_link: str | None = None
) -> UrdfChain:
    """The serial chain of the URDF ``path`` from ``base_link`` to ``tool_link`` (defaults: the
    module docstring).

    Raises:
        UrdfError: unreadable file, a link that does not exist, a tool link not below the base
            link, a floating or planar joint or a mimic joint in the chain, a zero joint axis, or
            a revolute/prismatic joint without a valid ``<limit>``.
    """
    path = Path(path)
    robot = _load(path)
    joints = list(robot.joints)
    _check_tree(path, joints)
    links = [link.name for link in robot.links]
    for key, link in (("base_link", base_link), ("tool_link", tool_link)):
        if link is not None and link not in links:
            raise UrdfError(
                f"{path}: no link named {link!r} (links: {', '.join(links)})",
                fix=f"give --{key.replace('_', '-')} (or [urdf] {key}) one of the URDF's link "
                "names",
            )
    if base_link is None:
        base_link = _default_base(path, joints, links)
    if tool_link is None:
        tool_link = _default_tool(path, joints, links, base_link)
    by_child = {j.child: j for j in joints}
    path_joints, link = [], tool_link
    while link != base_link:
        if link not in by_child:
            raise UrdfError(
                f"{path}: link {tool_link!r} is not below link {base_link!r}",
                fix="give --base-link (or [urdf] base_link) an ancestor of the tool link",
            )
        path_joints.append(by_child[link])
        link = by_child[link].parent
    path_joints.reverse()
    G, names, types, limits = [], [], [], []
    T = np.eye(4)
    for j in path_joints:
        origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
        where = f"{path}: joint {j.name!r}"
        if origin.shape != (4, 4) or not np.isfinite(origin).all():
            raise UrdfError(f"{where}: <origin> must be finite numbers (xyz, rpy: 3 each)",
                            fix=f"give {j.name!r} an <origin xyz=... rpy=...> of numbers")  # fmt: skip
        if j.type == "fixed":
            with np.errstate(over="ignore", invalid="ignore"):  # checked after the loop
                T = T @ origin
            continue
        if j.type in ("floating", "planar"):
            raise UrdfError(
                f"{where} is {j.type}: a serial arm's chain needs revolute, continuous, "
                "prismatic or fixed joints",
                fix=f"choose base_link/tool_link so that the chain avoids {j.name!r}",
            )
        if j.mimic is not None:
            raise UrdfError(
                f"{where} mimics joint {j.mimic.joint!r}: coupled joints are not supported",
                fix=f"end the chain (tool_link) before {j.name!r} or make it independent",
            )
        axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, float)
        if axis.shape != (3,) or not np.isfinite(axis).all():
            raise UrdfError(f"{where}: <axis xyz> must be 3 finite numbers",
                            fix=f"give {j.name!r} a unit <axis>")  # fmt: skip
        if not np.linalg.norm(axis) > 0:
            raise UrdfError(f"{where}: zero joint axis", fix=f"give {j.name!r} a unit <axis>")
        R = _z_onto(axis / np.linalg.norm(axis))
        with np.errstate(over="ignore", invalid="ignore"):  # checked after the loop
            G.append(T @ origin @ R)
        T = inv_pose(R)
        names.append(str(j.name))
        if j.type == "continuous":
            types.append("revolute")
            limits.append((-CONTINUOUS_LIMIT, CONTINUOUS_LIMIT))
            continue
        types.append("revolute" if j.type == "revolute" else "prismatic")
        lim = j.limit
        lo = None if lim is None else lim.lower
        hi = None if lim is None else lim.upper
        if lo is None or hi is None or not float(lo) < float(hi):
            raise UrdfError(
                f"{where}: needs <limit lower=... upper=...> with lower < upper",
                fix=f"add the joint range to {j.name!r} in {path}",
            )
        limits.append((float(lo), float(hi)))
    G.append(T)
    with np.errstate(over="ignore", invalid="ignore"):  # checked here: origins near 1e308
        chain = np.array(G)
        finite = bool(np.isfinite(chain).all())
    if not finite:
        raise UrdfError(
            f"{path}: the chain {base_link} -> {tool_link} does not compose to finite "
            "transforms (an <origin> too large for floating point)",
            fix="give the joints' <origin xyz> in metres, a robot's size",
        )
    return UrdfChain(
        name=str(robot.name or ""),
        base_link=base_link,
        tool_link=tool_link,
        joint_names=tuple(names),
        joint_types=tuple(types),
        limits=np.array(limits, dtype=float).reshape(-1, 2),
        chain=chain,
    )


def urdf_home(joint_types: tuple[str, ...], limits: np.ndarray) -> np.ndarray:
    """Home posture (deg for revolute, mm for prismatic joints, like ``home_deg``) of a robot
    loaded straight from a URDF: joint value 0, or the middle of the range where 0 is outside."""
    lim = np.asarray(limits, dtype=float)
    q = np.where((lim[:, 0] <= 0) & (lim[:, 1] >= 0), 0.0, lim.mean(axis=1))
    unit = np.array([180 / np.pi if t == "revolute" else 1000.0 for t in joint_types])
    return q * unit
