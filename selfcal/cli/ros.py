"""ROS bags on the command line (docs/ros.md): the ``--bag`` options of ``selfcal import``,
``selfcal export`` and ``selfcal run``. Degrees and seconds at this edge, SI inside."""

from __future__ import annotations

import argparse
import glob
import json
import re
from pathlib import Path

import numpy as np

from selfcal.choices import BAG_FORMATS, JOINT_TOPIC
from selfcal.console.common import CliError, note_written
from selfcal.ros.bag_rest import RestRule

__all__ = ["BAG_FORMATS", "add_import_args", "bag_paths", "cmd_import_bag", "cmd_import_bag_poses",
           "add_export_args", "cmd_export_bag", "export_run"]  # fmt: skip

_RULE = RestRule()


def add_import_args(sp: argparse.ArgumentParser) -> None:
    """``--bag`` and its options on ``selfcal import`` (instead of ``--images`` / ``--joints``)."""
    g = sp.add_argument_group("from a ROS bag (docs/ros.md; needs scorbot-selfcal[ros])")
    g.add_argument("--bag", action="append", default=None, metavar="PATH",
                   help="ROS 1 .bag, ROS 2 bag folder (sqlite3 or mcap) or .mcap file; the "
                   "files of a split ROS 1 recording as one bag: repeat --bag or give a quoted "
                   "glob ('rec_*.bag')")  # fmt: skip
    g.add_argument(
        "--image-topic", action="append", default=None, metavar="NAME=TOPIC",
        help="one camera's Image or CompressedImage topic, e.g. cam0=/camera/image_raw (repeat "
        "per camera); its camera_info is the sibling topic",
    )  # fmt: skip
    g.add_argument("--joint-topic", default=JOINT_TOPIC,
                   help=f"JointState topic (default {JOINT_TOPIC})")  # fmt: skip
    g.add_argument("--rest-window", type=float, default=_RULE.window_s, metavar="S",
                   help=f"window centred on an image in which the arm must rest (default "
                   f"{_RULE.window_s:g} s)")  # fmt: skip
    g.add_argument("--rest-speed", type=float, default=np.degrees(_RULE.speed_rad_s),
                   metavar="DEG_PER_S", help="joint speed below which the arm rests, over the "
                   f"window (default {np.degrees(_RULE.speed_rad_s):g} deg/s; mm/s for a "
                   "prismatic joint)")  # fmt: skip
    g.add_argument("--max-gap", type=float, default=_RULE.max_gap_s, metavar="S",
                   help="longest pause of the joint messages within the window (default "
                   f"{_RULE.max_gap_s:g} s)")  # fmt: skip
    g.add_argument("--tf-parent", default=None, metavar="FRAME",
                   help="with --tf-child: take the flange poses from /tf (FRAME -> the child, "
                   "e.g. base_link) instead of joints; needs --setup, no --robot "
                   "(docs/handeye.md)")  # fmt: skip
    g.add_argument("--tf-child", default=None, metavar="FRAME",
                   help="the flange or tool frame of the /tf pose pair, e.g. tool0")  # fmt: skip
    g.add_argument("--per-rest", default="1", metavar="N|all",
                   help="keep at most N frames of each rest (default 1: the middle image of "
                   "each rest, one frame per posture; `calibrate` refuses two frames of one "
                   "posture as copies); all: every image at rest")  # fmt: skip


def cmd_import_bag(args: argparse.Namespace) -> int:
    """``selfcal import --bag``."""
    from selfcal.importing.camera_choice import camera_options
    from selfcal.importing.dataset import detection_summary
    from selfcal.ros.bag_import import ImageTopic, import_bag

    if args.images or args.joints:
        raise CliError("--bag replaces --images and --joints: give one or the other")
    if not args.image_topic:
        raise CliError("--bag needs --image-topic NAME=TOPIC (one per camera)")
    rule = _rule(args)
    per_rest = None if args.per_rest == "all" else _count(args.per_rest)
    topics = [ImageTopic.parse(s, default_name=f"cam{k}") for k, s in enumerate(args.image_topic)]
    models, free = camera_options(args.camera_model, args.free, [c.name for c in topics],
                                  "--image-topic")  # fmt: skip
    bags = bag_paths(args.bag)
    info = import_bag(bags if len(bags) > 1 else bags[0], topics, args.joint_topic, args.robot,
                      args.target, args.out,
                      rule=rule, per_rest=per_rest, base_link=args.base_link,
                      tool_link=args.tool_link, camera_model=models, free=free)  # fmt: skip
    n = len(info.planned_joints_deg)
    note_written(args, args.out)
    src = str(bags[0]) if len(bags) == 1 else f"{len(bags)} bag files ({bags[0]} ...)"
    print(f"{detection_summary(info)}; imported {n} frames of {len(info.cameras)} camera(s) "
          f"from {src} into {args.out}")  # fmt: skip
    return 0


def cmd_import_bag_poses(args: argparse.Namespace) -> int:
    """``selfcal import --bag BAG --tf-parent BASE --tf-child FLANGE --setup SETUP``."""
    from selfcal.ros.bag_import import ImageTopic
    from selfcal.ros.bag_poses import import_bag_poses

    if not (args.tf_parent and args.tf_child):
        raise CliError("--tf-parent and --tf-child go together",
                       fix="name both frames: --tf-parent base_link --tf-child tool0")  # fmt: skip
    if args.images or args.joints or args.poses:
        raise CliError("--bag with --tf-parent/--tf-child replaces --images, --joints and --poses")
    if args.robot or args.base_link or args.tool_link or args.joint_units:
        raise CliError("--robot, --base-link, --tool-link and --joint-units describe joints",
                       fix="leave them out: flange poses from /tf need no robot model")  # fmt: skip
    if args.pose_units or args.rotation:
        raise CliError("--pose-units and --rotation describe a --poses file",
                       fix="leave them out: /tf holds metres and quaternions")  # fmt: skip
    if not args.setup:
        raise CliError("--tf-child needs --setup eye-in-hand | eye-to-hand",
                       fix="eye-in-hand: the camera rides on the flange; eye-to-hand: the camera "
                       "is static and the board rides on the flange")  # fmt: skip
    if not args.image_topic or len(args.image_topic) != 1:
        raise CliError("--tf-child takes one camera: one --image-topic NAME=TOPIC",
                       fix="import each camera as its own pose dataset")  # fmt: skip
    if args.camera_model and len(args.camera_model) > 1 or args.free and len(args.free) > 1:
        raise CliError("--tf-child takes one camera: one --camera-model and one --free")
    rule = _rule(args)
    per_rest = None if args.per_rest == "all" else _count(args.per_rest)
    model = (args.camera_model[0].partition("=")[2] or args.camera_model[0]
             if args.camera_model else None)  # fmt: skip
    free = (args.free[0].partition("=")[2] or args.free[0]).split(",") if args.free else None
    bags = bag_paths(args.bag)
    ds = import_bag_poses(bags if len(bags) > 1 else bags[0], ImageTopic.parse(args.image_topic[0]),
                          args.tf_parent, args.tf_child, args.target, args.out, args.setup,
                          rule=rule, per_rest=per_rest, camera_model=model, free=free)  # fmt: skip
    n = len(ds.T_base_flange)
    note_written(args, args.out)
    if args.json:
        print(json.dumps({"dataset": str(args.out), "frames": n, "setup": ds.setup}))
    else:
        print(f"imported {n} frames ({ds.setup}, flange poses {args.tf_parent} -> "
              f"{args.tf_child} from /tf) into {args.out}")  # fmt: skip
    return 0


def _rule(args: argparse.Namespace) -> RestRule:
    """The rest test of the ``--rest-*`` and ``--max-gap`` options."""
    for name, v in (("--rest-window", args.rest_window), ("--rest-speed", args.rest_speed),
                    ("--max-gap", args.max_gap)):  # fmt: skip
        if not v > 0:
            raise CliError(f"{name} {v}: give a positive number")
    return RestRule(window_s=args.rest_window, speed_rad_s=float(np.radians(args.rest_speed)),
                    speed_m_s=args.rest_speed / 1e3, max_gap_s=args.max_gap)  # fmt: skip


def _count(text: str) -> int:
    """``--per-rest``'s number (1 or more)."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise CliError(f"--per-rest {text}: give a number of 1 or more, or all")
    return n


def bag_paths(specs: list[str]) -> list[Path]:
    """The bags of the ``--bag`` options: each a path, or a glob (``'rec_*.bag'``) expanded in
    natural order (``rec_2`` before ``rec_10``); a glob that matches nothing is an error."""
    out: list[Path] = []
    for spec in specs:
        p = Path(spec).expanduser()
        if p.exists() or not any(ch in spec for ch in "*?["):
            out.append(p)
            continue
        found = sorted(glob.glob(str(p)), key=_natural)
        if not found:
            raise CliError(f"--bag {spec}: no file matches the pattern; give the bag files of "
                           "the recording (quote the glob)")  # fmt: skip
        out += [Path(f) for f in found]
    return list(dict.fromkeys(out))


def _natural(name: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def add_export_args(sp: argparse.ArgumentParser) -> None:
    """``--bag OUT`` on ``selfcal export`` (``--format ros1|ros2|mcap`` then names the format)."""
    sp.add_argument("--bag", default=None, metavar="OUT",
                    help="write the DATASET as a ROS bag instead (--format ros1 | ros2 | mcap; "
                    "default: ros1 for OUT.bag, mcap (one bare file) for OUT.mcap, else ros2); "
                    "see docs/ros.md")  # fmt: skip


def cmd_export_bag(args: argparse.Namespace) -> int:
    """``selfcal export DATASET --bag OUT [--format ros1|ros2|mcap]``."""
    from selfcal.ros.bag_export import export_bag

    if args.out:
        raise CliError("--bag writes the dataset as a bag; --out exports a calibration: give one")
    if args.format is not None and args.format not in BAG_FORMATS:
        raise CliError(f"--format {args.format} with --bag: use one of {', '.join(BAG_FORMATS)}")
    res = export_bag(args.calibration, args.bag, args.format)
    note_written(args, args.bag)
    print(json.dumps(res.to_json()))
    return 0


def export_run(dataset: Path, bag: str, quiet: bool) -> None:
    """``selfcal run --bag OUT``: the run's dataset as a bag (format from OUT's suffix)."""
    from selfcal.ros.bag_export import export_bag

    res = export_bag(dataset, bag)
    if not quiet:
        print(f"ROS bag ({res.format}): {res.path} ({res.frames} frames)")
