"""`selfcal --help` and `selfcal fk` stay light: the parser's modules import the heavy libraries
only in the commands that use them (issue 17). Checked in a fresh interpreter by sys.modules,
not by timing."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = (
    "mujoco",
    "matplotlib",
    "scipy.stats",
    "selfcal.sim",
    "selfcal.pipeline.run",
    "selfcal.acquisition.backends",
    "rich",  # the progress bars import it when they first draw (selfcal.console.progress)
)
PARSER_HEAVY = ("scipy", "cv2")  # also not needed to build the parser


def _loaded(code: str) -> list[str]:
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_importing_the_cli_and_building_its_parser_loads_no_heavy_module():
    mods = _loaded("import selfcal.cli.main as c\nc.build_parser()")
    assert "selfcal.cli.main" in mods  # the probe did import it
    assert [m for m in HEAVY + PARSER_HEAVY if m in mods] == []


@pytest.mark.parametrize(
    "argv",
    [
        ["fk", "--joints", "0,0,0,0,0"],  # the ER-4u (DH table), with pitch and roll
        ["fk", "--robot", "ur5e", "--joints", "10,-20,30,-40,50,60"],  # 6 axes: no pitch, roll
    ],
)
def test_fk_loads_no_scipy_simulator_or_plotting(argv):
    """`selfcal fk` (0.5 s of its 0.84 s was importing scipy.spatial) needs numpy only."""
    mods = _loaded(
        "import contextlib, io, sys\nimport selfcal.cli.main as c\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        f"    code = c.main({argv!r})\n"
        "assert code == 0 and 'quat_wxyz' in out.getvalue(), out.getvalue()"
    )
    assert "selfcal.kinematics.forward" in mods  # fk ran
    assert [m for m in HEAVY + PARSER_HEAVY if m in mods] == []


def test_the_light_choices_name_the_camera_models():
    from selfcal.camera import MODELS
    from selfcal.choices import CAMERA_MODELS, DEFAULT_FREE, DEFAULT_MODEL

    assert CAMERA_MODELS == tuple(MODELS) == tuple(DEFAULT_FREE)
    assert DEFAULT_MODEL in MODELS
    for name, free in DEFAULT_FREE.items():
        assert set(free) <= set(MODELS[name].names)


OTHER_ROUTES = (
    "selfcal.calibration.board.dataset",
    "selfcal.calibration.board.calibrate",
    "selfcal.calibration.board.accuracy",
    "selfcal.pipeline.board_accuracy",
    "selfcal.calibration.field.holdout",
    "selfcal.acquisition.eye_to_hand",
    "selfcal.sim.static_camera",
    "selfcal.target.placement",
)
"""What a marker-field `selfcal run` never calls: the board route's calibration and accuracy,
the own-data report's hold-out and the eye-to-hand simulator (issue 32: 29 modules, 0.05 s of
the run's start-up on the critical path)."""


def test_the_run_pipeline_loads_no_serial_link_nor_the_other_routes():
    """A simulated `selfcal run` imports the pipeline; the serial link's modules (pyserial, the
    ACL driver) load only for a hardware robot (selfcal.acquisition.backends.open_robot), the
    other routes' modules where those routes run."""
    mods = _loaded("import selfcal.pipeline.run")
    assert "selfcal.acquisition.backends" in mods  # the probe did import it
    assert [m for m in ("serial", "selfcal.hw.acl.robot", "selfcal.acquisition.hardware")
            if m in mods] == []  # fmt: skip
    assert [m for m in OTHER_ROUTES if m in mods] == []


def test_the_acquisition_loads_no_scipy():
    """`selfcal run` imports the acquisition before its first frame, and the acquisition needs no
    scipy (issue 32: ~0.3 s of the serial start): the D-optimal planner and the joints file's
    reader load it where they run. Setups are :data:`selfcal.choices.SETUPS`, not the pose
    datasets' module (which loads scipy.spatial)."""
    mods = _loaded("import selfcal.acquisition.acquire, selfcal.acquisition.backends")
    assert "selfcal.acquisition.backends" in mods  # the probe did import it
    assert [m for m in mods if m == "scipy" or m.startswith("scipy.")] == []


def test_the_run_pipeline_loads_no_scipy_spatial():
    """The calibration's rotations are numpy (selfcal.transforms): scipy.spatial (k-d trees,
    hulls, distances) and scipy.special, which it loads, are off `selfcal run`'s serial start
    (issue 32: 0.04 s on one core before the first frame)."""
    mods = _loaded("import selfcal.pipeline.run")
    assert "selfcal.calibration.field.calibrate" in mods  # the probe did import it
    assert [m for m in ("scipy.spatial", "scipy.special") if m in mods] == []


def test_the_board_accuracy_loads_no_scipy_stats():
    """`selfcal calibrate` of a field dataset loads the board accuracy too (the run pipeline's
    report: selfcal.pipeline.board_accuracy); scipy.stats (about 24 MB resident and 0.3-0.8 s)
    loads only where a board's model error is judged (selfcal.calibration.board.held_null's
    counted_excess): at import it grew a field's 30-posture `selfcal calibrate` peak from
    173.1 to 194.5 MB (python -m selfcal.benchmarks.speed.measure --memory)."""
    mods = _loaded("import selfcal.calibration.board.accuracy")
    assert "selfcal.calibration.board.held_null" in mods  # the probe did import it
    assert "scipy.stats" not in mods


def test_the_setups_are_one_tuple():
    from selfcal.choices import SETUPS
    from selfcal.config.camera import SETUPS as CONFIG_SETUPS
    from selfcal.io.poses.dataset import SETUPS as POSE_SETUPS

    assert SETUPS == ("eye-in-hand", "eye-to-hand")
    assert CONFIG_SETUPS is SETUPS and POSE_SETUPS is SETUPS
