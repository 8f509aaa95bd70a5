"""The transform tree of a bag (``/tf_static`` and ``/tf``, ``tf2_msgs/TFMessage``): where each
camera's frame is rigidly attached, recorded by ``selfcal import --bag`` as a hand-eye hint.

A hint, never truth: the calibration does not read it. An edge (parent -> child) is rigid when
it comes from ``/tf_static`` or never changes on ``/tf`` (within 1e-9 m / 1e-9 of a rotation
matrix entry); the edges between the arm's links move with the joints. From a camera's frame
(the images' ``header.frame_id``) :meth:`TfTree.rigid_parent` walks up the rigid edges to the
first frame whose edge to its parent moves (or that has no parent): on an arm with the camera on
the flange that is the flange or tool link (``tool0``), and the composed transform is the
camera's pose on it (the hand-eye); for a camera fixed in the lab it is the world or the robot's
base. A camera's pose relative to the base through the moving links changes with every posture,
so none is recorded. Frames: ``T_parent_camera`` maps camera-frame coordinates (the camera
driver's frame, ROS's optical frame when the driver stamps that) to the parent's, metres.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.transforms import make_pose

__all__ = ["TF_TYPE", "TF_TOPICS", "TfTree"]

TF_TYPE = "tf2_msgs/msg/TFMessage"
TF_TOPICS = ("/tf_static", "/tf")


def _frame(name: str) -> str:
    return str(name).lstrip("/")


class TfTree:
    """The rigid edges of a bag's transform tree, fed one ``TFMessage`` at a time."""

    def __init__(self) -> None:
        self._edge: dict[str, tuple[str, np.ndarray]] = {}  # child -> (parent, T_parent_child)
        self._moving: set[str] = set()  # children whose edge changed on /tf
        self.messages = 0

    def add(self, msg: Any, static: bool) -> None:
        """The transforms of one ``TFMessage`` (``static``: from ``/tf_static``)."""
        self.messages += 1
        for tr in msg.transforms:
            t, r = tr.transform.translation, tr.transform.rotation
            T = make_pose(Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix(), [t.x, t.y, t.z])
            parent, child = _frame(tr.header.frame_id), _frame(tr.child_frame_id)
            old = self._edge.get(child)
            if static or old is None:
                self._edge[child] = (parent, T)
                if static:
                    self._moving.discard(child)
            elif old[0] != parent or not np.allclose(old[1], T, rtol=0, atol=1e-9):
                self._moving.add(child)

    def rigid_parent(self, frame: str) -> tuple[str, np.ndarray, list[str]] | None:
        """``(parent, T_parent_frame, path)``: the frame ``frame`` is rigidly attached to (module
        docstring), the composed transform (4, 4, m) and the frames walked; None when ``frame``
        is not in the tree or its own edge moves."""
        frame = _frame(frame)
        if frame not in self._edge or frame in self._moving:
            return None
        T, path, f = np.eye(4), [frame], frame
        while f in self._edge and f not in self._moving and len(path) <= len(self._edge):
            parent, T_pf = self._edge[f]
            T, f = T_pf @ T, parent
            path.append(f)
        return f, T, path

    def hint(self, frames: dict[str, str]) -> dict:
        """The record for dataset.json: per camera name its frame and where it is rigidly
        attached (``T_parent_camera`` in m), or why not."""
        out: dict[str, Any] = {}
        for cam, frame in frames.items():
            got = self.rigid_parent(frame) if frame else None
            if got is None:
                why = ("the images carry no frame_id" if not frame else
                       f"frame {frame!r} is not in the bag's /tf_static or /tf, or moves")  # fmt: skip
                out[cam] = {"frame": frame, "rigidly_on": None, "why": why}
                continue
            parent, T, path = got
            out[cam] = {"frame": _frame(frame), "rigidly_on": parent, "path": path,
                        "T_parent_camera": np.round(T, 12).tolist()}  # fmt: skip
        return out
