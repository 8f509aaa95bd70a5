"""``selfcal plan --target FIELD.toml``: the postures to record over a marker field (the field
route, the paper's self-calibration), the command of :mod:`selfcal.calibration.field.plan`:
writes PLAN/joints.csv, trajectory.yaml, scenario.toml (the plan replayed over a simulated field)
and plan.json. Eye-in-hand only so far."""

from __future__ import annotations

import argparse
import json
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from selfcal.calibration.field.plan import FieldLayout
    from selfcal.camera import CameraModel
    from selfcal.sim.markers import MarkerField

from selfcal.console.common import CliError, note_written, writing
from selfcal.errors import EstimationError, InputError, SelfCalError, SelfCalWarning

__all__ = ["FIELD_EPILOG", "add_field_options", "check_field_options", "cmd_field", "is_field"]

FIELD_DEFAULTS = {"markers": 20, "field_extent_mm": 300.0, "marker_mm": 30.0, "clear_views": False}
"""The field options' defaults: the simulated scenarios' field (``[target]`` of
:mod:`selfcal.config.scenario`)."""

FIELD_EPILOG = """\
--target FIELD.toml (type = "field", with its scale_marker_ids and scale_length_mm): a plan over
a marker field for the field route (the camera's focal length and lens, the markers' positions
and the kinematics estimated, the scale from the one known distance). The field lies on the
table (z = 0) in a square of --field-extent-mm centred where the home posture's optical axis
meets it (as the simulated field does); every posture shows each camera at least 6 points of a
6 x 6 grid over it (the planner's visibility rule), lies within the joint ranges and is free of
self-collision, the table and the keep-out boxes. The forecast is the field route's Cramer-Rao
bound of the flange centre's error over 50 workspace postures (the plan's and a random plan's
of the same size) for --markers markers of --marker-mm laid as scenario.toml's simulated field
lays them; the postures are, of --candidates random ones, the choice with the least forecast
of four: the field route's D-optimal choice, the board plan's greedy choice and exchange on the
predicted tool-point error with the markers' corners known, and the best of these exchanged
with the corners unknown, as the route estimates them (plan.json's chosen_by and
choices_tool_rms_mm). A plan of
fewer than 30 postures whose forecast is behind a random plan of 30's says so and gives the
count whose plan is not (plan.json's count_to_match: this plan grown one posture at a time
on the corners-unknown criterion).
Eye-in-hand, one camera; --board-pose, --camera-pose and --mount eye-to-hand are refused,
as is --add to a field's dataset.
See docs/plan.md.
"""


def add_field_options(sp: argparse.ArgumentParser) -> None:
    """The options of a plan over a marker field (their defaults None: refused with a board)."""
    sp.add_argument("--markers", type=int, default=None,
                    help="a marker field: its markers (default 20)")  # fmt: skip
    sp.add_argument("--field-extent-mm", type=float, default=None, metavar="MM",
                    help="a marker field: the side of the square it covers, mm (default 300)")  # fmt: skip
    sp.add_argument("--marker-mm", type=float, default=None, metavar="MM",
                    help="a marker field: the printed markers' side, mm (default 30)")  # fmt: skip
    sp.add_argument("--clear-views", action="store_true", default=None,
                    help="a marker field: no posture whose camera shows a marker of the replay's "
                    "field partly hidden by a raised support (the detector may return its "
                    "corners off; costs forecast, docs/plan.md)")  # fmt: skip


def is_field(path: str) -> bool:
    """Whether the target TOML ``path`` declares a marker field (errors name the file)."""
    from selfcal.io.target_toml import load_target
    from selfcal.target import ArucoField

    return isinstance(load_target(path), ArucoField)


def check_field_options(args: argparse.Namespace) -> None:
    """A clear error for a field's option given with a board or ``--add``, and for ``--add`` to
    a marker field's dataset (its additions are not planned yet)."""
    given = [f"--{k.replace('_', '-')}" for k in FIELD_DEFAULTS if getattr(args, k) is not None]
    if given:
        raise CliError(f"{', '.join(given)} describe{'s' if len(given) == 1 else ''} a marker "
                       "field (--target FIELD.toml), not a board or a dataset",
                       fix=f"leave out {', '.join(given)}")  # fmt: skip
    if args.add:
        from selfcal.calibration.routes import dataset_route
        from selfcal.io.dataset_info import DatasetError

        try:
            route = dataset_route(args.add[1])
        except DatasetError:  # no dataset: the board's --add says so after its option checks
            return
        if route == "field":
            raise CliError(f"--add {' '.join(args.add)}: the additions to a marker field's "
                           "dataset are not planned yet (--add takes a board dataset)",
                           fix="plan the field anew with selfcal plan --robot ROBOT --target "
                           "FIELD.toml --count N and record that plan")  # fmt: skip


def _check(args: argparse.Namespace) -> None:
    """The refusals of a field plan (what is not supported yet, with the fix)."""
    from selfcal.calibration.field.failures import MIN_POSTURES

    if args.mount == "eye-to-hand":
        raise CliError("a plan over a marker field is eye-in-hand only so far (the field route "
                       "calibrates a camera on the flange over a field on the table)",
                       fix="give --mount eye-in-hand, or a board target (e.g. "
                       "models/targets/charuco.toml) with --mount eye-to-hand")  # fmt: skip
    given = [o for o, v in (("--board-pose", args.board_pose), ("--camera-pose", args.camera_pose))
             if v]  # fmt: skip
    if given:
        raise CliError(f"{given[0]}: a marker field lies where the home posture looks (its "
                       "centre where the home optical axis meets the table); another place is "
                       "not supported yet", fix=f"leave out {given[0]}")  # fmt: skip
    for key, d in FIELD_DEFAULTS.items():
        setattr(args, key, d if getattr(args, key) is None else getattr(args, key))
    args.count = 12 if args.count is None else args.count
    if args.count < MIN_POSTURES:
        raise CliError(f"--count {args.count}: the field route calibrates from {MIN_POSTURES} "
                       f"postures at the least", fix=f"give --count {MIN_POSTURES} or more")  # fmt: skip
    if args.markers < 4 or args.field_extent_mm <= 0 or args.marker_mm <= 0:
        raise CliError(f"--markers {args.markers}, --field-extent-mm {args.field_extent_mm:g}, "
                       f"--marker-mm {args.marker_mm:g}: give at least 4 markers and positive "
                       "sizes", fix="e.g. the defaults: --markers 20 --field-extent-mm 300 "
                       "--marker-mm 30")  # fmt: skip


def replay_layout(scenario: Path, scale_m: float) -> tuple[FieldLayout, MarkerField]:
    """The simulated marker field of the replay ``scenario`` (a plan's ``scenario.toml``) as the
    forecast's :class:`~selfcal.calibration.field.plan.FieldLayout` (world frame, m; the scale
    ``scale_m`` between its two scale markers; its raised supports, which can hide a marker)
    and the field itself
    (:class:`~selfcal.sim.markers.MarkerField`). Raises the scenario's or the field's
    :class:`~selfcal.errors.SelfCalError`."""
    from selfcal.acquisition.simulator_setup import sim_setup
    from selfcal.calibration.field.plan import FieldLayout
    from selfcal.calibration.field.plan_sight import Supports
    from selfcal.config.scenario import load_scenario

    f = sim_setup(load_scenario(scenario)).marker_field()
    ids = (int(f.scale_ids[0]), int(f.scale_ids[1]))
    sup = Supports(*f.support_boxes(), tile_ratio=f.tile_size_m / f.size_m)
    return FieldLayout(f.ids, f.corners_world(), f.T_world_marker[:, :3, 2], ids, scale_m,
                       sup), f  # fmt: skip


def _warn_unlike_the_replay(target: str, dictionary: str, scale_ids: tuple[int, int]) -> None:
    """A warning when the target file's dictionary or scale markers are not the simulated
    field's: the postures and the forecast hold for the user's field (they depend on its extent,
    markers and scale length), the replay's ``scenario.toml`` simulates the other one."""
    from selfcal.io.target_toml import load_field_scale, load_target

    theirs = (getattr(load_target(target), "dictionary", None), load_field_scale(target)[0])
    if theirs != (dictionary, tuple(int(i) for i in scale_ids)):
        warnings.warn(f"{target}: dictionary {theirs[0]}, scale markers {list(theirs[1])}; the "
                      f"replay's scenario.toml simulates a {dictionary} field with scale markers "
                      f"{[int(i) for i in scale_ids]} (the postures and the forecast depend on "
                      "the field's extent, markers and scale length only)", SelfCalWarning,
                      stacklevel=3)  # fmt: skip


def forecast_words(markers: int, scale_mm: float, free: tuple[str, ...], workspace: int) -> str:
    """What the forecast includes and what not (plan.json's ``criterion``, the second line)."""
    return (f"the field route's Cramer-Rao bound of the flange centre's RMS error over {workspace} "
            f"workspace postures after the best rigid alignment, estimating the camera "
            f"({', '.join(free)}), the {markers} markers' corners (positions unknown), the joints' "
            "read-back errors and every kinematic parameter, the scale from the one known "
            f"distance ({scale_mm:g} mm), at the nominal chain; a bound, not an achieved error: "
            "the estimator's and the detector's losses and the comparison with the fair nominal "
            "are not in it")  # fmt: skip


def cmd_field(
    args: argparse.Namespace,
    camera_of: Callable[[argparse.Namespace], CameraModel],
    deviation_of: Callable[[argparse.Namespace], object],
) -> int:
    """``selfcal plan`` over the marker field ``args.target`` (see :data:`FIELD_EPILOG`);
    ``camera_of`` and ``deviation_of`` read the camera and the arm's deviation as a board plan
    does. Returns the exit code."""
    import numpy as np

    from selfcal.acquisition.backends import robot_reference
    from selfcal.calibration.field.joint_refine import encoder_sigma
    from selfcal.calibration.field.plan import (
        MATCH_RANDOM,
        FieldPlanSetup,
        field_forecast,
        forecast_workspace,
        plan_field,
    )
    from selfcal.camera import Rig
    from selfcal.cli.plan_args import (
        check_common,
        keep_out_boxes,
        plan_inputs,
        trajectory_joint_names,
        write_postures,
    )
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.plan_files import write_plan
    from selfcal.io.target_toml import load_field_scale
    from selfcal.kinematics.trajectory import DegenerateTrajectoryError
    from selfcal.robot.definition import load_robot

    _check(args)
    check_common(args, args.count)
    (_, _), scale_m = load_field_scale(args.target)
    robot = load_robot(args.robot)
    names = trajectory_joint_names(args, robot.joint_names)
    camera = camera_of(args)
    boxes = keep_out_boxes(args)
    setup = FieldPlanSetup(robot, Rig((camera,), np.eye(4)[None], ("left",)),
                           args.field_extent_mm / 1000.0, boxes, clear_views=args.clear_views)  # fmt: skip
    js = encoder_sigma(robot)
    ref = robot_reference(args.robot)
    field = {"markers": args.markers, "extent_mm": float(args.field_extent_mm),
             "marker_size_mm": float(args.marker_mm), "scale_length_mm": scale_m * 1000.0}  # fmt: skip
    # the forecast's markers are the replay's simulated field: built (and checked) before planning
    scenario = scenario_text(ref, camera, None, args.count, deviation=deviation_of(args),
                             field=field, pixel_sigma=args.pixel_sigma)  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        write_text_atomic(Path(tmp) / "scenario.toml", scenario)
        try:
            layout, fld = replay_layout(Path(tmp) / "scenario.toml", scale_m)
        except SelfCalError as e:  # the field's options: named, not the temporary file's keys
            why = e.message.replace(f"{Path(tmp) / 'scenario.toml'}: ", "")
            raise CliError(f"--markers {args.markers}, --field-extent-mm "
                           f"{args.field_extent_mm:g}, --marker-mm {args.marker_mm:g} and "
                           f"{args.target}'s scale_length_mm {scale_m * 1000:g} make no "
                           f"simulated field: {why}",
                           fix="e.g. the defaults --markers 20 --field-extent-mm 300 "
                           "--marker-mm 30; at most 48 markers (DICT_4X4_50 less the two "
                           "scale markers), a scale length inside the extent") from e  # fmt: skip
    _warn_unlike_the_replay(args.target, fld.dictionary, fld.scale_ids)
    try:  # the workspace the forecast averages over: where the plan's choice is judged too
        ws = forecast_workspace(setup, seed=args.seed + 1)
        plan = plan_field(setup, args.count, layout, ws, seed=args.seed,
                          candidates=args.candidates, markers=args.markers,
                          pixel_sigma_px=args.pixel_sigma, joint_sigma=js)  # fmt: skip
    except (DegenerateTrajectoryError, InputError) as e:
        raise CliError(f"no field plan of {args.count} postures: {e.message}",
                       fix="free the arm's room (fewer or smaller --keep-out boxes), give more "
                       "--candidates, a camera that sees the field from more postures "
                       "(a wider --fov-deg), or plan without --clear-views") from e  # fmt: skip
    n = len(plan.q)
    scenario = scenario_text(ref, camera, None, n, deviation=deviation_of(args), field=field,
                             pixel_sigma=args.pixel_sigma)  # fmt: skip
    fc = {k: field_forecast(setup, layout, q, ws, pixel_sigma_px=args.pixel_sigma,
                            joint_sigma=js) for k, q in (("plan", plan.q), ("random", plan.q_random))}  # fmt: skip
    plan_rms, random_rms = fc["plan"].tool_rms_m, fc["random"].tool_rms_m
    if plan_rms is None:
        raise EstimationError(f"the plan of {n} postures over the field does not determine the "
                              f"field route's unknowns: {fc['plan'].why}",
                              fix="give a larger --count (the 12 of docs/plan.md's example "
                              "determine them), more --markers or a camera with fewer free "
                              "parameters")  # fmt: skip
    plan_mm = round(plan_rms * 1000, 4)
    random_mm = None if random_rms is None else round(random_rms * 1000, 4)
    if random_mm is not None and plan_mm > random_mm:
        warnings.warn(f"the field plan's forecast ({plan_mm:.3f} mm) is behind the random "
                      f"plan's ({random_mm:.3f} mm)", SelfCalWarning, stacklevel=2)  # fmt: skip
    out = Path(args.out)
    with writing(args, out):
        write_postures(args, out, names, plan.q, robot)
        write_text_atomic(out / "scenario.toml", scenario)
        criterion = forecast_words(args.markers, scale_m * 1000, camera.free, len(ws))
        body = {
            "robot": ref,
            "mount": "eye-in-hand",
            "count": n,
            "predicted_tool_rms_mm": plan_mm,
            "random_tool_rms_mm": random_mm,
            "predicted_fx_std_px": fc["plan"].fx_std_px,
            "random_fx_std_px": fc["random"].fx_std_px,
            "no_bound": {k: f.why for k, f in fc.items() if f.tool_rms_m is None},
            "chosen_by": plan.chosen_by,
            "random_match_count": MATCH_RANDOM,
            "random_match_tool_rms_mm": _mm(plan.random_match_m),
            "count_to_match": None if plan.to_match is None else plan.to_match[0],
            "count_to_match_tool_rms_mm": None if plan.to_match is None else _mm(plan.to_match[1]),
            "count_to_match_joints_deg": _match_deg(plan, robot.edge_unit),
            "choices_tool_rms_mm": {
                k: None if v is None else round(v * 1000, 4) for k, v in plan.choices.items()
            },  # fmt: skip
            "criterion": criterion,
            "field": field,
            "candidates": plan.candidates,
            "clear_views": bool(args.clear_views),
            "path_deg": round(float(np.degrees(plan.path_rad)), 3),
            "random_path_deg": round(float(np.degrees(plan.random_path_rad)), 3),
            "seed": args.seed,
            **plan_inputs(args, boxes, robot.edge_unit, plan.q, plan.q_random),
        }
        doc = write_plan(out / "plan.json", "field", body)
    note_written(args, out)
    print(json.dumps(doc) if args.json else _lines(plan, fc, n, criterion))
    return 0


def _match_deg(plan, edge_unit) -> list | None:
    """The advised plan's postures (``plan.match``) in edge units (deg), None without one."""
    import numpy as np

    if plan.match is None or plan.pool is None:
        return None
    return np.round(plan.pool[plan.match] / edge_unit, 6).tolist()


def _mm(m: float | None) -> float | None:
    """A forecast in m as plan.json's mm (None stays None)."""
    return None if m is None else round(m * 1000, 4)


def _lines(plan, fc: dict, n: int, criterion: str) -> str:
    """The closing lines of a field plan: the forecasts, what they are and, for a plan behind
    the random plan of :data:`selfcal.calibration.field.plan.MATCH_RANDOM`, the count that is
    not."""
    import numpy as np

    from selfcal.calibration.field.plan import MATCH_RANDOM

    def mm(f) -> str:
        return f"{f.tool_rms_m * 1000:.3f} mm" if f.tool_rms_m is not None else f"none ({f.why})"

    text = (f"field plan of {n} postures: predicted tool-point error {mm(fc['plan'])} RMS "
            f"(a random plan of {n}: {mm(fc['random'])}); joint path "
            f"{np.degrees(plan.path_rad):.0f} deg (random {np.degrees(plan.random_path_rad):.0f} "
            f"deg)\nthe forecast: {criterion}")  # fmt: skip
    r = plan.random_match_m
    if r is None or fc["plan"].tool_rms_m is None or fc["plan"].tool_rms_m <= r:
        return text
    more = ("no plan of up to that many reaches it" if plan.to_match is None else
            f"a plan of {plan.to_match[0]} reaches it (this plan grown on its criterion: "
            f"{plan.to_match[1] * 1000:.3f} mm): give --count {plan.to_match[0]}")  # fmt: skip
    return (f"{text}\nbehind the forecast of a random plan of {MATCH_RANDOM} postures "
            f"({r * 1000:.3f} mm); {more}")  # fmt: skip
