"""The plan's trajectory.yaml times each move by every joint's own speed (a prismatic joint's in
m/s, not the revolute joints' rad/s read as m/s)."""

from __future__ import annotations

import numpy as np

from selfcal.io.plan_files import trajectory_doc


def _seconds(point: dict) -> float:
    d = point["time_from_start"]
    return d["sec"] + d["nanosec"] * 1e-9


def test_a_prismatic_joint_moves_at_its_own_speed() -> None:
    # 10 deg/s revolute, 10 mm/s prismatic (selfcal plan --speed-deg-s 10 on an R-P arm)
    speed = 10.0 * np.array([np.pi / 180.0, 1e-3])
    q = np.array([[np.radians(5.0), 0.0], [np.radians(5.0), 0.2]])
    doc = trajectory_doc(["j1", "j2"], q, np.zeros(2), speed=speed, dwell_s=1.0)
    t = [_seconds(p) for p in doc["points"]]
    assert np.isclose(t[0], 0.5)  # 5 deg at 10 deg/s
    assert np.isclose(t[2] - t[1], 20.0)  # 200 mm at 10 mm/s (1.15 s if read as 0.1745 m/s)


def test_one_speed_serves_every_joint() -> None:
    q = np.array([[0.3, -0.6]])
    doc = trajectory_doc(["a", "b"], q, np.zeros(2), speed=0.2, dwell_s=2.0)
    assert [_seconds(p) for p in doc["points"]] == [3.0, 5.0]
