"""``python -m selfcal.benchmarks.drift.choose``'s check images (review 29, findings 3 and 6): a
view keeps the corners the command's stated power counts (by the true chain), not every corner in
the image; the table names the robot and prints an upper-bound power as "at most"."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from selfcal.benchmarks.drift.choose import CORNERS, table, view_corners
from selfcal.calibration.board.plan.views import PlanSetup, seen_features
from selfcal.calibration.drift.choose import check_cell
from selfcal.io.camera_file import camera_from_fov
from selfcal.io.target_toml import load_target
from selfcal.robot.definition import load_robot, models_dir
from selfcal.transforms import inv_pose


def _cell() -> PlanSetup:
    """A check's cell (views of part of the board) of the UR5e and the shipped ChArUco."""
    board = load_target(models_dir() / "targets/charuco.toml")
    return check_cell(PlanSetup(load_robot("ur5e"), camera_from_fov(60.0, 640, 480), board,
                                np.eye(4)))  # fmt: skip


def _part_view(setup: PlanSetup, dx: float = 0.15, dy: float = 0.0) -> np.ndarray:
    """(4, 4) board -> camera: the optical axis along the board's normal, moved ``dx``, ``dy``
    m along the board's x, y axes from its centre, 0.4 m away (part of the board out of the
    image)."""
    _, X = setup.board.layout()
    T = np.eye(4)
    T[:3, 3] = -X.mean(axis=0) + [dx, dy, 0.4]
    return T


def test_a_check_view_keeps_the_corners_the_stated_power_counts():
    """A view of part of the board: the corners kept are exactly those seen_features expects
    there (the cells about each corner in the image with the rule's margin), fewer than the
    corners in the image (which the benchmark used to keep), with the same noisy pixels; a
    camera calibrated a little wrong does not change the set (the true camera decides)."""
    setup = _cell()
    T_cb = _part_view(setup)
    ids = setup.board.layout()[0]
    want = set(ids[seen_features(setup, T_cb[None])[0]].tolist())
    T_world_cam, T_world_board = inv_pose(T_cb), np.eye(4)
    got = view_corners(setup, setup.camera, setup.board, T_world_cam, T_world_board,
                       sigma_px=0.2, rng=np.random.default_rng(3))  # fmt: skip
    every = view_corners(setup, setup.camera, setup.board, T_world_cam, T_world_board,
                         sigma_px=0.2, rng=np.random.default_rng(3), all_in_image=True)  # fmt: skip
    assert len(want) >= setup.rule.min_corners
    assert set(got) == want
    assert want < set(every)  # the image shows more than the power counted
    assert all(np.array_equal(got[i], every[i]) for i in got)
    off = replace(setup, camera=camera_from_fov(61.0, 640, 480))  # the calibration's camera
    assert set(view_corners(off, setup.camera, setup.board, T_world_cam, T_world_board,
                            sigma_px=0.2, rng=np.random.default_rng(3))) == want  # fmt: skip


def test_a_view_with_too_few_expected_corners_is_empty():
    """A view whose expected corners are fewer than the board's least is left out (empty),
    even when more corners are in the image."""
    setup = _cell()
    ids = setup.board.layout()[0]
    for dx, dy in ((a, b) for a in np.linspace(0.1, 0.3, 21) for b in np.linspace(0, 0.2, 21)):
        T_cb = _part_view(setup, float(dx), float(dy))
        k = int(seen_features(setup, T_cb[None])[0].sum())
        every = view_corners(setup, setup.camera, setup.board, inv_pose(T_cb), np.eye(4),
                             sigma_px=0.0, rng=np.random.default_rng(0), all_in_image=True)  # fmt: skip
        if 0 < k < setup.board.min_features <= len(every):
            break
    else:
        raise AssertionError("no view with a few expected corners and more in the image")
    assert len(ids) > len(every)
    assert view_corners(setup, setup.camera, setup.board, inv_pose(T_cb), np.eye(4),
                        sigma_px=0.0, rng=np.random.default_rng(0)) == {}  # fmt: skip


def test_the_table_names_the_robot_the_corners_and_upper_bounds():
    """A row names its robot and which corners were checked; a power that is an upper bound
    in every calibration reads "at most", in some of them says how many."""
    row = {"setup": "eye-to-hand, ur5e", "noise_px": 0.2, "calibrations": 30, "checks": 300,
           "corners": CORNERS[False], "code": "abc1234", "chosen_power": 0.9998,
           "chosen_upper": 30, "random_power": 0.9, "random_upper": 4}  # fmt: skip
    for s in ("chosen", "random"):
        row |= {f"{s}_{k}": 0 for k in ("tool", "unchanged", "unchanged_cannot_tell",
                                        "tool_cannot_tell")}  # fmt: skip
    text = table([row])
    assert "| eye-to-hand, ur5e |" in text and f"| {CORNERS[False]} |" in text
    assert "| chosen | at most 100.0 % |" in text
    assert "| random | 90.0 % (4 of 30 at most) |" in text
    assert "--all-in-image" not in text
    assert "--all-in-image" in table([row | {"corners": CORNERS[True]}])
