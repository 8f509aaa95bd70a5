"""The files of a recording plan (``selfcal plan``): the postures as a joints CSV in
``selfcal import``'s format and as a ROS ``trajectory_msgs/JointTrajectory`` in YAML.

- ``joints.csv``: a header ``j1..jn`` and one row per posture, degrees (mm for a prismatic
  joint), six decimals: what :func:`selfcal.io.tracker.read_joint_rows` reads back.
- ``trajectory.yaml``: ``joint_names`` from the robot file and one point per posture with
  ``positions`` (rad; m for a prismatic joint), zero ``velocities`` and ``time_from_start``
  (``sec``, ``nanosec``: ROS 2's ``builtin_interfaces/Duration``), then the same positions
  again ``dwell_s`` later (the arm rests there while the images are taken). The times assume
  the arm starts at home and every joint moves at its ``speed`` (rad/s; m/s for a prismatic
  joint) at most.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import yaml

__all__ = ["joints_csv", "trajectory_doc", "trajectory_yaml"]


def joints_csv(q: np.ndarray, edge_unit: np.ndarray) -> str:
    """``q`` (m, n) SI as the text of a joints CSV (module docstring); ``edge_unit`` (n,) the SI
    value of one edge unit per joint (rad per deg, m per mm: ``RobotDef.edge_unit``)."""
    q = np.atleast_2d(np.asarray(q, dtype=float)) / np.asarray(edge_unit, dtype=float)
    lines = [",".join(f"j{k + 1}" for k in range(q.shape[1]))]
    lines += [",".join(f"{v:.6f}" for v in row) for row in q]
    return "\n".join(lines) + "\n"


def _duration(t: float) -> dict[str, int]:
    ns = int(round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def trajectory_doc(
    joint_names: Sequence[str],
    q: np.ndarray,
    start: np.ndarray,
    *,
    speed: float | np.ndarray,
    dwell_s: float,
) -> dict:
    """The JointTrajectory (module docstring) as plain data; ``speed`` is one speed for every
    joint or (n,) one per joint (rad/s; m/s for a prismatic joint)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    speed = np.broadcast_to(np.asarray(speed, dtype=float), q.shape[1:])
    pts, t, prev = [], 0.0, np.asarray(start, dtype=float)
    zeros = [0.0] * q.shape[1]
    for row in q:
        t += max(float(np.max(np.abs(row - prev) / speed)), 0.1)
        for at in (t, t + dwell_s):
            pts.append({"positions": [round(float(v), 9) for v in row], "velocities": list(zeros),
                        "accelerations": [], "effort": [],
                        "time_from_start": _duration(at)})  # fmt: skip
        t += dwell_s
        prev = row
    return {"header": {"frame_id": ""}, "joint_names": list(joint_names), "points": pts}


def trajectory_yaml(
    joint_names: Sequence[str],
    q: np.ndarray,
    start: np.ndarray,
    *,
    speed: float | np.ndarray,
    dwell_s: float,
) -> str:
    """:func:`trajectory_doc` as YAML text."""
    doc = trajectory_doc(joint_names, q, start, speed=speed, dwell_s=dwell_s)
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
