"""A bag's transform tree over time: the pose of one frame in another at any stamp, and when it rested.

``selfcal import --bag BAG --tf-parent base_link --tf-child tool0`` takes the flange poses from
``/tf`` (and ``/tf_static``) instead of joint readings. Every ``TransformStamped`` is kept by its
child frame with its own header stamp (ns). An edge from ``/tf_static``, or one whose transform
never changes, is constant; a moving edge is interpolated at a stamp (translation linearly,
rotation by spherical interpolation between the two neighbouring messages) and undefined outside
its messages. ``T_parent_child(t)`` composes the edges from both frames up to their common root.
Metres and rotation matrices inside.

:meth:`TfSeries.track` samples that pose at the stamps of the moving edges on the path as a
:class:`selfcal.ros.bag_rest.JointTrack` of 12 numbers (x, y, z in m and the rotation matrix's
nine entries, each changing by at most the turn in rad), so the rest test of ``--bag`` imports
(:class:`selfcal.ros.bag_rest.RestRule`: mm/s for the position, deg/s for the turn) applies to
poses as it does to joints.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from selfcal.ros.bag_rest import NS, JointTrack
from selfcal.ros.rosbag import BagError
from selfcal.transforms import inv_pose, make_pose

__all__ = ["TfSeries"]

_SAME = 1e-9
"""m, and rotation-matrix entries: an edge whose messages all agree this closely is constant."""


def _frame(name: str) -> str:
    return str(name).lstrip("/")


@dataclass
class _Edge:
    parent: str
    static: bool = False
    t: list[int] = field(default_factory=list)
    T: list[np.ndarray] = field(default_factory=list)

    def moves(self) -> bool:
        if self.static or len(self.T) < 2:
            return False
        T = np.asarray(self.T)
        return bool(np.abs(T - T[0]).max() > _SAME)


class TfSeries:
    """Every transform of a bag's ``/tf_static`` and ``/tf`` by child frame (module docstring),
    fed one ``TFMessage`` at a time; ``where`` names the bag in errors."""

    def __init__(self, where: str) -> None:
        self.where = where
        self._edge: dict[str, _Edge] = {}
        self.messages = 0

    def add(self, msg: Any, static: bool, stamp: int) -> None:
        """The transforms of one ``TFMessage`` (``static``: from ``/tf_static``; ``stamp``: the
        message's time in ns, used where a transform's own header stamp is zero)."""
        self.messages += 1
        for tr in msg.transforms:
            t, r = tr.transform.translation, tr.transform.rotation
            T = make_pose(Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix(), [t.x, t.y, t.z])
            parent, child = _frame(tr.header.frame_id), _frame(tr.child_frame_id)
            own = int(tr.header.stamp.sec) * NS + int(tr.header.stamp.nanosec)
            edge = self._edge.get(child)
            if edge is None or edge.parent != parent or (static and not edge.static):
                edge = self._edge[child] = _Edge(parent, static)
            if static:
                edge.t, edge.T = [own or stamp], [T]
            else:
                edge.t.append(own or stamp)
                edge.T.append(T)

    def _up(self, frame: str) -> list[str]:
        """``frame`` and its ancestors, up to the root."""
        path = [frame]
        while path[-1] in self._edge and len(path) <= len(self._edge):
            path.append(self._edge[path[-1]].parent)
        return path

    def _path(self, parent: str, child: str) -> tuple[list[str], list[str]]:
        """The frames below the common root on the child's side and on the parent's side."""
        known = set(self._edge) | {e.parent for e in self._edge.values()}
        for opt, f in (("--tf-parent", parent), ("--tf-child", child)):
            if f not in known:
                raise BagError(
                    f"{self.where}: {opt} {f!r} is not a frame of /tf or /tf_static (frames: "
                    f"{', '.join(sorted(known)) or 'none: the bag has no transforms'})",
                    fix="name the robot's base and flange (tool) frames as /tf publishes them",
                )
        up_c, up_p = self._up(child), self._up(parent)
        common = next((f for f in up_c if f in up_p), None)
        if common is None:
            raise BagError(
                f"{self.where}: no chain of transforms joins {parent!r} and {child!r} on /tf "
                f"({child!r} hangs from {up_c[-1]!r}, {parent!r} from {up_p[-1]!r})",
                fix="give two frames of the robot's tree (the base and the flange or tool link)",
            )
        return up_c[: up_c.index(common)], up_p[: up_p.index(common)]

    def _at(self, child: str, t: np.ndarray) -> np.ndarray:
        """The edge of ``child`` at stamps ``t`` (k,) ns: (k, 4, 4), NaN outside its messages."""
        e = self._edge[child]
        if not e.moves():
            return np.broadcast_to(e.T[-1], (len(t), 4, 4)).copy()
        ts = np.asarray(e.t, np.int64)
        order = np.argsort(ts, kind="stable")
        ts, Ts = ts[order], np.asarray(e.T)[order]
        keep = np.append(ts[1:] != ts[:-1], True)  # a repeated stamp keeps its last message
        ts, Ts = ts[keep], Ts[keep]
        out = np.full((len(t), 4, 4), np.nan)
        inside = (t >= ts[0]) & (t <= ts[-1])
        if len(ts) == 1 or not inside.any():
            out[inside] = Ts[0]
            return out
        x = (ts - ts[0]).astype(float)
        xi = (t[inside] - ts[0]).astype(float)
        R = Slerp(x, Rotation.from_matrix(Ts[:, :3, :3]))(xi).as_matrix()
        p = np.stack([np.interp(xi, x, Ts[:, j, 3]) for j in range(3)], axis=1)
        out[inside] = make_pose(R, p)
        return out

    def lookup(self, parent: str, child: str, t: np.ndarray) -> np.ndarray:
        """``T_parent_child`` (k, 4, 4) m at the stamps ``t`` (k,) ns; NaN where a moving edge
        on the way has no messages around the stamp.

        Raises:
            BagError: a frame that is not in the tree, or two frames no chain joins.
        """
        t = np.atleast_1d(np.asarray(t, np.int64))
        side_c, side_p = self._path(_frame(parent), _frame(child))
        T_c = np.broadcast_to(np.eye(4), (len(t), 4, 4)).copy()
        for f in side_c:  # root ... -> child: left-multiply each edge going up
            T_c = self._at(f, t) @ T_c
        T_p = np.broadcast_to(np.eye(4), (len(t), 4, 4)).copy()
        for f in side_p:
            T_p = self._at(f, t) @ T_p
        return inv_pose(T_p) @ T_c

    def track(self, parent: str, child: str) -> JointTrack:
        """``T_parent_child`` sampled at every message of the moving edges between the two
        frames, as a 12-number :class:`JointTrack` (module docstring) for the rest test.

        Raises:
            BagError: as :meth:`lookup`, or no edge between the frames moves (the pair does not
                follow the robot).
        """
        parent, child = _frame(parent), _frame(child)
        side_c, side_p = self._path(parent, child)
        moving = [f for f in side_c + side_p if self._edge[f].moves()]
        if not moving:
            raise BagError(
                f"{self.where}: the transform {parent} -> {child} never changes on /tf (every "
                f"edge between them is static: {', '.join(side_c + side_p) or 'the same frame'})",
                fix="give the frames the robot moves between: its base (--tf-parent) and its "
                "flange or tool link (--tf-child)",
            )
        t = np.unique(np.concatenate([np.asarray(self._edge[f].t, np.int64) for f in moving]))
        T = self.lookup(parent, child, t)
        ok = np.isfinite(T).all(axis=(1, 2))
        vec = np.concatenate([T[ok, :3, 3], T[ok, :3, :3].reshape(-1, 9)], axis=1)
        return JointTrack(t[ok], vec, ("prismatic",) * 3 + ("revolute",) * 9)
