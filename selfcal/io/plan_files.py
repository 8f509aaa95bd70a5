"""The files of a recording plan (``selfcal plan``): the postures as a joints CSV in
``selfcal import``'s format and as a ROS ``trajectory_msgs/JointTrajectory`` in YAML, and
``plan.json``'s one writer and one reader.

- ``joints.csv``: a header ``j1..jn`` and one row per posture, degrees (mm for a prismatic
  joint), six decimals: what :func:`selfcal.io.tracker.read_joint_rows` reads back.
- ``trajectory.yaml``: ``joint_names`` from the robot file and one point per posture with
  ``positions`` (rad; m for a prismatic joint), zero ``velocities`` and ``time_from_start``
  (``sec``, ``nanosec``: ROS 2's ``builtin_interfaces/Duration``), then the same positions
  again ``dwell_s`` later (the arm rests there while the images are taken). The times assume
  the arm starts at home and every joint moves at its ``speed`` (rad/s; m/s for a prismatic
  joint) at most.
- ``plan.json``: ``format`` (:data:`PLAN_FORMAT`), ``schema_version``
  (:data:`PLAN_SCHEMA_VERSION`) and ``kind`` (:data:`PLAN_KINDS`) first, then the command's
  sections in its order (:func:`write_plan`, what every ``selfcal plan`` writes through);
  :func:`read_plan` checks the three, every reader of a plan goes through it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml

from selfcal.errors import InputError, UsageError
from selfcal.io.jsonfile import (
    SCHEMA_KEY,
    UPGRADE_FIX,
    Fields,
    check_header,
    load_json,
    write_json_atomic,
)

__all__ = [
    "PLAN_FORMAT",
    "PLAN_KINDS",
    "PLAN_SCHEMA_VERSION",
    "joints_csv",
    "read_plan",
    "trajectory_doc",
    "trajectory_yaml",
    "write_plan",
]

PLAN_FORMAT = "scorbot-selfcal-plan"
PLAN_SCHEMA_VERSION = 1
"""``plan.json``'s schema: raise it when a key changes in a way older code cannot read."""
PLAN_KINDS = ("camera", "add", "field", "tracker", "check", "tracker-add")
"""``plan.json``'s ``kind``: a camera plan over a board, ``--add K DATASET``, a plan over a
marker field, ``--measure tracker``, ``--check K CALIBRATION`` (a drift check's postures),
``--add K DIR`` to a tracker calibration."""
_PLAN_FIX = "re-create it with `selfcal plan ... --out DIR` (docs/plan.md)"


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


def write_plan(path: str | Path, kind: str, body: dict) -> dict:
    """Write ``plan.json`` at ``path`` (atomically, :func:`selfcal.io.jsonfile.dumps`'s form):
    ``format``, ``schema_version`` and ``kind`` (one of :data:`PLAN_KINDS`), then ``body``'s
    keys in their order. Returns the document written (what ``selfcal plan --json`` prints).

    Raises:
        UsageError: ``kind`` is not one of :data:`PLAN_KINDS`, or ``body`` holds a header key.
    """
    if kind not in PLAN_KINDS:
        raise UsageError(f"plan.json kind {kind!r}: not one of {', '.join(PLAN_KINDS)}")
    if header := {"format", SCHEMA_KEY, "kind"} & body.keys():
        raise UsageError(f"plan.json's body holds the header's {', '.join(sorted(header))}")
    doc = {"format": PLAN_FORMAT, SCHEMA_KEY: PLAN_SCHEMA_VERSION, "kind": kind, **body}
    write_json_atomic(path, doc)
    return doc


def read_plan(path: str | Path, kinds: Sequence[str] = PLAN_KINDS) -> dict:
    """The ``plan.json`` at ``path`` (the document :func:`write_plan` wrote), whose ``kind`` is
    one of ``kinds``.

    Raises:
        InputError: missing, not JSON, another ``format``, a ``schema_version`` newer than
            :data:`PLAN_SCHEMA_VERSION`, or a ``kind`` not in ``kinds`` (the message names the
            file and the key, the fix what to do).
    """
    doc = load_json(path, fix=_PLAN_FIX)
    where = str(path)
    check_header(doc, where, fmt=PLAN_FORMAT, version=PLAN_SCHEMA_VERSION, fix=_PLAN_FIX)
    kind = Fields(doc, where, _PLAN_FIX).str("kind")
    if kind in PLAN_KINDS and kind not in kinds:
        want = " or ".join(kinds)
        raise InputError(
            f"{where}: key 'kind' is {kind!r}; a plan of kind {want} is read here",
            fix=f"give the folder of a `selfcal plan` of kind {want} (docs/plan.md)",
        )
    if kind not in kinds:
        raise InputError(
            f"{where}: key 'kind' is {kind!r}, which this scorbot-selfcal does not know (it "
            f"reads {', '.join(PLAN_KINDS)})",
            fix=UPGRADE_FIX,
        )
    return doc
