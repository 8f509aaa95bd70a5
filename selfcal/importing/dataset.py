"""``selfcal import``: your own images and joint readings as a dataset folder.

Inputs: a robot (model name, robot TOML or URDF; a URDF with ``base_link`` / ``tool_link`` gets
a small robot TOML in the dataset that names them), the images of N >= 1 cameras (a glob per
camera name), a joints file (:func:`selfcal.io.tracker.read_joint_rows`, the one joints reader) and a
target TOML (a board, or a marker field with its one known distance: :mod:`selfcal.importing.field`). Rows of the joints
file match the images in sorted file-name order, or through its ``image`` column (the file name
every camera's folder holds for that frame). Checked, each an :class:`selfcal.errors.InputError`
naming the file and the fix: row and image counts, joint units, one image size per camera, the
target found in at least one image (the others are named, counted and skipped with a
:class:`TargetNotFoundWarning`, apart from those in which OpenCV found the board but the
detector's checks refused it, each with the reason), and the board's declared geometry against
the detections (:func:`selfcal.calibration.board.calibrate.calibrate_board`). Any number of frames imports (a
held-out set for ``selfcal evaluate`` may have one); the calibration's minimum is
:data:`selfcal.calibration.board.dataset.MIN_FRAMES`. ``dataset.json``'s ``provenance.detection`` counts the
images searched, those with the target and those in which OpenCV alone found it: its own
detector with its default parameters (``Board.detection``; for an ArUco field the project's
detector, and the summary line gives no OpenCV count) (:func:`detection_summary`). Writes ``dataset.json`` (schema 2, no truth),
``joints.csv`` (deg), ``frames/NNNN_CAMERA.EXT`` (copies or symbolic links) and ``sources.csv``
(where every frame came from).
"""

from __future__ import annotations

import csv
import glob
import os
import re
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.camera import MODELS, canonical_free
from selfcal.choices import DEFAULT_FREE, DEFAULT_MODEL
from selfcal.importing.camera_choice import for_cameras
from selfcal.importing.checks import (
    ImportError_,
    TargetNotFoundWarning,
    _counts,
    _min_features,
    check_geometry,
    detection_summary,
    warn_not_found,
)
from selfcal.importing.field import FieldTarget, field_target
from selfcal.io.dataset_info import DatasetInfo, write_dataset_info
from selfcal.io.images import read_gray_image
from selfcal.io.outlock import removed_on_failure
from selfcal.io.target_toml import load_target, target_document
from selfcal.io.tracker import read_joint_rows
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.robot.urdf import urdf_chain
from selfcal.target import ArucoField
from selfcal.target.board_detect import Detection
from selfcal.target.boards import Board
from selfcal.tomlfile import read_toml

__all__ = [
    "ImportError_",
    "TargetNotFoundWarning",
    "CameraImages",
    "check_geometry",
    "name_order",
    "import_dataset",
    "detection_summary",
    "detect_images",
    "camera_choice",
]

_ROWS_SHOWN = 5
"""How many rows an error lists before "...": enough to see a pattern."""


def name_order(name: str) -> tuple[list[str | int], str]:
    """Sort key of an image file name: numbers by value (``img_2`` before ``img_10``, as a
    camera's unpadded counter means them), the rest as text."""
    return [int(t) if k % 2 else t for k, t in enumerate(re.split(r"(\d+)", name))], name


@dataclass(frozen=True)
class CameraImages:
    """One ``--images NAME=GLOB``: the camera's name and its image files (sorted by name,
    :func:`name_order`)."""

    name: str
    pattern: str
    files: tuple[Path, ...]

    @classmethod
    def parse(cls, spec: str, default_name: str = "cam0") -> CameraImages:
        """``NAME=GLOB`` (or a bare ``GLOB`` for a camera called ``default_name``)."""
        name, sep, pattern = spec.partition("=")
        if not sep:
            name, pattern = default_name, spec
        name = name.strip()
        if not name or not all(ch.isalnum() or ch in "-_" for ch in name):
            raise ImportError_(
                f"--images {spec!r}: camera name {name!r}",
                fix="name each camera with letters, digits, - or _: --images 'cam0=DIR/*.png'",
            )
        # the whole path in name order: files of one folder by name, folders (run1/, run2/
        # from a 'DIR/*/*.png' or 'DIR/**/*.png' pattern) one after the other
        files = tuple(sorted((Path(p) for p in glob.glob(os.path.expanduser(pattern),
                                                         recursive=True)),
                             key=lambda p: name_order(str(p))))  # fmt: skip
        files = tuple(p for p in files if p.is_file())
        if not files:
            raise ImportError_(f"--images {spec!r}: no file matches {pattern!r}",
                               fix="check the folder and the pattern (quote it)")  # fmt: skip
        return cls(name, pattern, files)


def _robot(
    spec: str, base_link: str | None, tool_link: str | None, out: Path
) -> tuple[RobotDef, str]:
    """The robot and how dataset.json names it (a model name, or a file in the dataset)."""
    p = Path(spec)
    if p.suffix not in (".toml", ".urdf"):
        if base_link or tool_link:
            raise ImportError_("--base-link / --tool-link name links of a URDF",
                               fix="give --robot FILE.urdf with them")  # fmt: skip
        return load_robot(spec), spec
    if not p.is_file():
        raise ImportError_(f"--robot {spec}: no such file",
                           fix="give a model name, a robot TOML or a URDF file")  # fmt: skip
    if p.suffix == ".urdf":  # errors name the user's file, not the dataset's copy
        urdf_chain(p, base_link=base_link, tool_link=tool_link)
    (out / "robot").mkdir(parents=True, exist_ok=True)
    if p.suffix == ".toml" or not (base_link or tool_link):
        if base_link or tool_link:
            raise ImportError_("--base-link / --tool-link apply to a URDF only",
                               fix="name the links in the robot TOML's [urdf] table")  # fmt: skip
        if p.suffix == ".toml":
            load_robot(p)  # errors name the user's file, not the dataset's copy
        shutil.copy2(p, out / "robot" / p.name)
        if p.suffix == ".toml":
            _copy_urdf_of(p, out / "robot")
        rel = f"robot/{p.name}"
    else:
        shutil.copy2(p, out / "robot" / p.name)
        links = "".join(f'{k} = "{v}"\n' for k, v in (("base_link", base_link),
                                                       ("tool_link", tool_link)) if v)  # fmt: skip
        (out / "robot" / f"{p.stem}.toml").write_text(
            f'name = "{p.stem}"\ndescription = "{p.name}, chain named by selfcal import"\n\n'
            f'[urdf]\nfile = "{p.name}"\n{links}\n'
            "# the camera at the tool link, looking along its z axis (the nominal hand-eye)\n"
            "[camera_mount]\nxyz_mm = [0.0, 0.0, 0.0]\nx_axis = [1.0, 0.0, 0.0]\n"
            "z_axis = [0.0, 0.0, 1.0]\n"
        )
        rel = f"robot/{p.stem}.toml"
    return load_robot(out / rel), rel


def _copy_urdf_of(toml: Path, folder: Path) -> None:
    """Copy the URDF that the robot TOML ``toml`` names in ``[urdf] file`` next to its copy in
    ``folder`` (the copy's ``file`` then names it without a folder), so the dataset can move."""
    table = read_toml(toml).get("urdf")
    if not isinstance(table, dict) or "file" not in table:
        return
    given = str(table["file"])
    src = (toml.parent / given).resolve()
    shutil.copy2(src, folder / src.name)
    if given != src.name:
        text = (folder / toml.name).read_text()
        (folder / toml.name).write_text(
            re.sub(r'(?m)^(\s*file\s*=\s*)(["\']).*?\2', lambda m: f'{m[1]}"{src.name}"', text)
        )


LINK_TEXT_BYTES = 1024
"""At most this long, an unreadable image whose text names an existing file is taken for a
symbolic link saved as text."""


def _unreadable(f: Path) -> ImportError_:
    """The error of an image OpenCV cannot read; a short text file naming an existing file (a
    symbolic link that git, an archive or a copy wrote as text: a real set's ``images_calib/01.png``
    held ``../../examples/data/test_set_charuco/images/1.png``) names the file it points to."""
    text = ""
    try:
        if f.is_file():  # the head alone: an unreadable image may be large
            with f.open("rb") as fh:
                text = fh.read(LINK_TEXT_BYTES + 1).decode("utf-8").strip()
    except (OSError, UnicodeDecodeError):
        text = ""
    target = f.parent / text if text and len(text) <= LINK_TEXT_BYTES and "\n" not in text else None
    if target is not None and target.is_file():
        return ImportError_(
            f"{f}: not an image but a {f.stat().st_size}-byte text naming {text}: a symbolic "
            "link saved as a text file (by git without symlink support, an archive or a copy)",
            fix=f"give --images the files the links name (here {target.resolve()}), or restore "
            "the links (git config core.symlinks true, then check the files out again)",
        )
    return ImportError_(f"{f}: not a readable image", fix="remove it or convert it to PNG")


def detect_images(
    cam: CameraImages, files: Sequence[Path], target: Board | FieldTarget, progress=None
) -> tuple[tuple[int, int], list[Detection]]:
    """The target's detection in every image (read gray, one at a time, so memory does not grow
    with the number of images) and the camera's one image size; two sizes are an error naming
    both files. ``progress``: advanced once per image (``advance()``)."""
    feats, first = [], None
    for f in files:
        if progress is not None:
            progress.advance()
        img = read_gray_image(f)
        if img is None:
            raise _unreadable(Path(f))
        size = (img.shape[1], img.shape[0])
        if first is None:
            first = (f, size)
        elif size != first[1]:
            raise ImportError_(
                f"camera {cam.name}: {first[0]} is {first[1][0]}x{first[1][1]} px but {f} is "
                f"{size[0]}x{size[1]} px",
                fix="give every image of one camera at the camera's native size (or give the "
                "other size as another camera)",
            )
        if isinstance(target, FieldTarget):
            found = target.field.detect(img)
            feats.append(Detection(found, len(found)))
        else:
            feats.append(target.detection(img))
    assert first is not None
    return first[1], feats


def import_dataset(
    robot: str,
    images: Sequence[CameraImages],
    joints: str | Path,
    joint_units: str,
    target: str | Path,
    out: str | Path,
    *,
    base_link: str | None = None,
    tool_link: str | None = None,
    link: bool = False,
    trust_units: bool = False,
    camera_model: str | Mapping[str, str] = DEFAULT_MODEL,
    free: Sequence[str] | Mapping[str, Sequence[str]] | None = None,
    source: dict | None = None,
    labels: Mapping[Path, str] | None = None,
    initial: Mapping[str, dict] | None = None,
    progress=None,
    setup: str = "eye-in-hand",
) -> DatasetInfo:
    """Check the inputs and write the dataset folder ``out`` (module docstring); returns its
    ``dataset.json`` content. ``trust_units``: skip the radians-looking check of degrees.
    ``camera_model`` (``"pinhole"``, ``"opencv"``, ``"fisheye"``) and ``free`` (OpenCV names;
    default :data:`DEFAULT_FREE` of the model): what the board calibration estimates, recorded
    in every camera entry of dataset.json; either may map camera names to each camera's own
    (a camera the mapping leaves out gets :data:`DEFAULT_MODEL` and its model's default free
    set). ``source`` (default: the joints file, its units, the
    target and the image patterns) is recorded as dataset.json's ``scenario.import``; ``labels``
    names an image file's origin in ``sources.csv`` (default: its resolved path); ``initial``:
    camera name -> the camera to start the calibration from (dataset.json's ``initial``:
    :attr:`selfcal.io.dataset.DatasetInfo.camera_initial`). ``progress``: an object with
    ``start(total)``, ``advance()``, ``finish()`` (``selfcal.console.progress.Progress``) advanced once
    per image detected. ``setup``: ``"eye-in-hand"`` (the cameras on the flange) or
    ``"eye-to-hand"`` (the cameras static, the board on the flange), recorded in dataset.json.
    A failed import leaves no folder behind that it created.

    Raises:
        ImportError_, selfcal.io.tracker.TrackerFileError, selfcal.calibration.board.calibrate
        .BoardInputError / BoardMismatchError, selfcal.robot.definition.RobotDefinitionError: bad input
        (each names the file and the fix).
    """
    with removed_on_failure(Path(out)):
        out = Path(out)
        names = [c.name for c in images]
        if not images or len(set(names)) != len(names):
            raise ImportError_(f"camera names {names}", fix="give each --images a distinct NAME=")
        choice = _camera_choices(names, camera_model, free)
        if (out / "dataset.json").exists():
            raise ImportError_(f"{out} already holds a dataset", fix="choose another --out folder")
        loaded = load_target(target)
        tgt: Board | FieldTarget
        if isinstance(loaded, ArucoField):
            if setup == "eye-to-hand":
                raise ImportError_(f"{target}: --setup eye-to-hand needs a board on the flange, "
                                   "not the ArUco field (the field's self-calibration has the "
                                   "cameras on the flange)",
                                   fix="give the board's target TOML with --target")  # fmt: skip
            tgt = field_target(target, loaded, names)
        else:
            assert isinstance(loaded, Board)  # every other target type is a board
            tgt = loaded
        out.mkdir(parents=True, exist_ok=True)
        rob, robot_ref = _robot(robot, base_link, tool_link, out)
        rows = read_joint_rows(joints, rob, joint_units, guess=not trust_units)
        files = _match(images, rows.images, len(rows.q), Path(joints))
        suffixes = {f.suffix.lower() for fs in files.values() for f in fs}
        if len(suffixes) != 1:
            raise ImportError_(f"images of several kinds {sorted(suffixes)}",
                               fix="convert the images to one format (e.g. PNG)")  # fmt: skip
        sizes, found = {}, {}
        if progress is not None:
            progress.start(sum(len(fs) for fs in files.values()))
        for cam in images:
            sizes[cam.name], found[cam.name] = detect_images(cam, files[cam.name], tgt, progress)
        if progress is not None:
            progress.finish()
        feats = {c: [d.features for d in ds] for c, ds in found.items()}
        seen = np.zeros(len(rows.q), bool)
        for cam in images:
            seen |= [len(f) >= _min_features(tgt) for f in feats[cam.name]]
        warn_not_found(tgt, images, files, found, labels or {})
        if not seen.any():
            raise ImportError_(
                f"the {tgt.describe()} is found in none of the {len(seen)} frames",
                fix="check the target file's keys against the printed board and add images that show "
                "the whole board",
            )
        if isinstance(tgt, FieldTarget):
            tgt.check_scale_seen(feats)
        for cam in images:
            if isinstance(tgt, Board):
                check_geometry(tgt, feats[cam.name], sizes[cam.name], *choice[cam.name])
        keep = np.flatnonzero(seen)
        (out / "frames").mkdir(exist_ok=True)
        suffix = suffixes.pop()
        with open(out / "sources.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["index", "camera", "source"])
            for k, r in enumerate(keep):
                for cam in images:
                    src = files[cam.name][r].resolve()
                    dst = out / "frames" / f"{k:04d}_{cam.name}{suffix}"
                    if link:
                        dst.symlink_to(src)
                    else:
                        shutil.copy2(src, dst)
                    label = labels.get(files[cam.name][r]) if labels else None
                    w.writerow([k, cam.name, label or str(src)])
        q_deg = np.degrees(rows.q[keep])
        with open(out / "joints.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["index"] + [f"q{j + 1}_deg" for j in range(rob.n)])
            for k, q in enumerate(q_deg):
                w.writerow([k] + [f"{v:.9f}" for v in q])
        res = tuple(sizes[c] for c in names)
        info = DatasetInfo(
            robot_model=robot_ref,
            resolution=res[0],
            dictionary="" if isinstance(tgt, Board) else tgt.field.dictionary,
            scale_ids=(0, 0) if isinstance(tgt, Board) else tgt.scale_ids,
            scale_length_m=0.0 if isinstance(tgt, Board) else tgt.scale_length_m,
            observation="images",
            planned_joints_deg=q_deg,
            validation_joints_deg=np.zeros((0,)),
            backend="import",
            provenance={"import": source or {"joints": str(joints), "joint_units": joint_units,
                      "target": str(target), "images": {c.name: c.pattern for c in images}},
                        "detection": _counts(tgt, found)},
            cameras=tuple(names),
            resolutions=None if len(set(res)) == 1 else res,
            board=target_document(tgt) if isinstance(tgt, Board) else None,
            image_suffix=suffix,
            camera_model=choice[names[0]][0],
            camera_free=choice[names[0]][1],
            camera_models=None if len(set(choice.values())) == 1 else tuple(choice.values()),
            camera_initial=tuple((initial or {}).get(c) for c in names) if initial else None,
            setup=setup,
        )  # fmt: skip
        write_dataset_info(out / "dataset.json", info)
        return info


def _camera_choices(
    cameras: Sequence[str],
    model: str | Mapping[str, str],
    free: Sequence[str] | Mapping[str, Sequence[str]] | None,
) -> dict[str, tuple[str, tuple[str, ...]]]:
    """Every camera's (model, free names), from one choice for all or a mapping by camera name
    (``import_dataset``'s ``camera_model`` and ``free``), each checked."""
    models = for_cameras(model, cameras, "--camera-model", "--images") if isinstance(
        model, Mapping) else dict.fromkeys(cameras, model)  # fmt: skip
    frees = for_cameras(free, cameras, "--free", "--images") if isinstance(
        free, Mapping) else dict.fromkeys(cameras, free)  # fmt: skip
    model_of = {c: models.get(c, DEFAULT_MODEL) for c in cameras}
    free_of = {c: None if (f := frees.get(c)) is None else tuple(f) for c in cameras}
    per = len(set(model_of.values())) > 1 or len(set(free_of.values())) > 1
    return {c: camera_choice(model_of[c], free_of[c], c if per else None)
            for c in cameras}  # fmt: skip


def camera_choice(
    model: str, free: Sequence[str] | None, camera: str | None = None
) -> tuple[str, tuple[str, ...]]:
    """The camera ``model`` and its ``free`` names (default :data:`DEFAULT_FREE`), checked;
    ``camera``: the camera they are for (named in the messages), None: every camera."""
    which = "" if camera is None else f"camera {camera}: "
    if model not in MODELS:
        raise ImportError_(f"{which}camera model {model!r}", fix=f"use one of {', '.join(MODELS)}")
    names = MODELS[model].names
    try:
        free_t = DEFAULT_FREE[model] if free is None else canonical_free(free)
    except ValueError as e:
        raise ImportError_(str(e), fix="give --free either fy or mu") from None
    bad = [n for n in free_t if n not in names]
    if bad or "fx" not in free_t:
        opt = "--free" if camera is None else f"--free '{camera}=...'"
        raise ImportError_(
            f"{which}free camera parameters {list(free_t)} for the {model} model",
            fix=f"give {opt} a comma list of {', '.join(names)} (fy for mu) that includes fx",
        )
    return model, tuple(n for n in names if n in free_t)


def _match(
    images: Sequence[CameraImages], column: tuple[str, ...] | None, n_rows: int, joints: Path
) -> dict[str, list[Path]]:
    """Every camera's image file of every joints row (sorted order, or the ``image`` column)."""
    out: dict[str, list[Path]] = {}
    for cam in images:
        if column is None:
            if len(cam.files) != n_rows:
                raise ImportError_(
                    f"{joints} has {n_rows} joint rows but camera {cam.name} has "
                    f"{len(cam.files)} images ({cam.pattern})",
                    fix="give one row per image (rows match the images in sorted file-name "
                    "order, numbers by value), or add an image column naming each row's file",
                )
            out[cam.name] = list(cam.files)
            continue
        by_name = {f.name: f for f in cam.files}
        if len(by_name) < len(cam.files):
            names = [f.name for f in cam.files]
            twice = sorted({n for n in names if names.count(n) > 1})
            raise ImportError_(
                f"camera {cam.name} ({cam.pattern}): file name(s) {twice[:3]} appear in more "
                f"than one folder, so {joints}'s image column cannot tell which is meant",
                fix="give each camera's images distinct file names, or leave out the image "
                "column (rows then match the files in path order)",
            )
        missing = [(k, n) for k, n in enumerate(column, start=1) if n not in by_name]
        if missing:
            shown = missing[:_ROWS_SHOWN]
            rows = ", ".join(str(k) for k, _ in shown) + (", ..." if missing[len(shown) :] else "")
            raise ImportError_(
                f"{joints}: the image column names {len(missing)} file(s) that camera "
                f"{cam.name} ({cam.pattern}) lacks, e.g. {missing[0][1]!r} (data row "
                f"{missing[0][0]}; rows {rows})",
                fix="add the missing images to the --images folder, or remove their rows from "
                "the joints file (the column holds file names only, no folders)",
            )
        out[cam.name] = [by_name[n] for n in column]
    return out
