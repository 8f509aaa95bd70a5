"""``selfcal import --poses``: one camera's images and the robot's flange poses as a pose dataset.

Inputs: the images (a glob, :class:`selfcal.importing.dataset.CameraImages`; or the image files an
industrial_calibration ``cal_data.yaml`` names), a flange pose file
(:func:`selfcal.io.poses.files.read_poses`: base -> flange, one row per image in sorted file-name
order or by its image column), the target TOML of a board and the setup (``eye-in-hand`` or
``eye-to-hand``, :data:`selfcal.choices.SETUPS`). Checked as ``selfcal import`` checks a
joints dataset: row and image counts, one image size, the board found (the others named, counted
and skipped with a :class:`selfcal.importing.dataset.TargetNotFoundWarning`), the declared geometry
against the detections. Writes :mod:`selfcal.io.poses.dataset`'s folder. No robot model is needed:
there are no kinematics to identify from poses.
"""

from __future__ import annotations

import csv
import io
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from selfcal.choices import DEFAULT_MODEL, SETUPS
from selfcal.importing.checks import ImportError_, check_geometry, warn_not_found
from selfcal.importing.dataset import CameraImages, camera_choice, detect_images
from selfcal.io.atomic import write_text_atomic
from selfcal.io.outlock import removed_on_failure
from selfcal.io.poses.dataset import PoseDataset, write_pose_dataset
from selfcal.io.poses.files import read_poses
from selfcal.io.target_toml import load_target, target_document
from selfcal.target.boards import Board

__all__ = ["MIN_POSE_FRAMES", "import_pose_dataset"]

MIN_POSE_FRAMES = 1
"""Fewest frames that show the board for a pose dataset to be imported (a held-out set may be
small; ``selfcal calibrate`` asks for more)."""


def _files(images: CameraImages | None, named: tuple[str, ...] | None, n: int,
           poses: Path) -> list[Path]:  # fmt: skip
    """The image file of every pose row."""
    if images is None:
        if named is None:
            raise ImportError_(f"{poses} names no images", fix="give --images 'cam0=DIR/*.png'")
        files = [Path(p) for p in named]
        missing = [f for f in files if not f.is_file()]
        if missing:
            raise ImportError_(f"{poses}: image {missing[0]} does not exist",
                               fix="check the image paths of the pose file")  # fmt: skip
        return files
    if named is None:
        if len(images.files) != n:
            raise ImportError_(
                f"{poses} has {n} poses but camera {images.name} has {len(images.files)} images "
                f"({images.pattern})",
                fix="give one pose per image (rows match the images in sorted file-name order, "
                "numbers by value), or add an image column naming each row's file",
            )
        return list(images.files)
    by_name = {f.name: f for f in images.files}
    out = []
    for k, name in enumerate(named):
        f = by_name.get(Path(name).name)
        if f is None:
            raise ImportError_(f"{poses}: row {k + 1}'s image {name!r} is not among {images.pattern}",
                               fix="name files of the --images folder in the image column")  # fmt: skip
        out.append(f)
    return out


def import_pose_dataset(
    images: CameraImages | None,
    poses: str | Path,
    target: str | Path,
    out: str | Path,
    setup: str,
    *,
    rotation: str | None = None,
    units: str | None = None,
    link: bool = False,
    camera_model: str = DEFAULT_MODEL,
    free: Sequence[str] | None = None,
    source: dict | None = None,
    labels: Mapping[Path, str] | None = None,
) -> PoseDataset:
    """Check the inputs and write the pose dataset ``out`` (module docstring); returns it.
    ``rotation``, ``units``: the pose file's convention and position unit where its header does
    not say (:func:`selfcal.io.poses.files.read_poses`); ``camera_model``, ``free``: what the
    calibration estimates (as ``selfcal import``); ``source``: what the poses and images came
    from (e.g. a bag and its topics), recorded instead of the pose file under
    ``provenance.import``; ``labels``: each image file's name in ``sources.csv`` (default its
    path). A failed import leaves no folder behind that it created.

    Raises:
        selfcal.importing.dataset.ImportError_, selfcal.io.poses.files.PoseFileError,
        selfcal.calibration.board.calibrate.BoardMismatchError: bad input, each naming the file and the fix.
    """
    if setup not in SETUPS:
        raise ImportError_(f"--setup {setup!r}", fix=f"use one of {', '.join(SETUPS)}")
    out = Path(out)
    if (out / "dataset.json").exists():
        raise ImportError_(f"{out} already holds a dataset", fix="choose another --out folder")
    model, free_t = camera_choice(camera_model, free)
    with removed_on_failure(out):
        rows = read_poses(poses, rotation, units)
        tgt = load_target(target)
        if not isinstance(tgt, Board):
            raise ImportError_(f"{target}: a pose dataset needs a board (chessboard, charuco, "
                               "circles, aprilgrid)", fix="give the board's target TOML")  # fmt: skip
        files = _files(images, rows.images, len(rows.T_base_flange), Path(poses))
        cam = images or CameraImages("cam0", str(poses), tuple(files))
        suffixes = {f.suffix.lower() for f in files}
        if len(suffixes) != 1:
            raise ImportError_(f"images of several kinds {sorted(suffixes)}",
                               fix="convert the images to one format (e.g. PNG)")  # fmt: skip
        size, found = detect_images(cam, files, tgt)
        warn_not_found(tgt, [cam], {cam.name: files}, {cam.name: found}, {})
        feats = [d.features for d in found]
        seen = np.array([len(f) >= tgt.min_features for f in feats])
        if seen.sum() < MIN_POSE_FRAMES:
            raise ImportError_(f"the {tgt.describe()} is found in none of {len(files)} images",
                               fix="check the target file's keys against the printed board")  # fmt: skip
        check_geometry(tgt, feats, size, model, free_t)
        keep = np.flatnonzero(seen)
        (out / "frames").mkdir(parents=True, exist_ok=True)
        suffix = suffixes.pop()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["index", "camera", "source"])
        for k, r in enumerate(keep.tolist()):
            src = files[r].resolve()
            dst = out / "frames" / f"{k:04d}_{cam.name}{suffix}"
            if link:
                dst.symlink_to(src)
            else:
                shutil.copy2(src, dst)
            w.writerow([k, cam.name, (labels or {}).get(files[r], str(src))])
        write_text_atomic(out / "sources.csv", buf.getvalue())
        ds = PoseDataset(
            root=out, setup=setup, camera=cam.name, resolution=size, model=model, free=free_t,
            board=target_document(tgt), T_base_flange=rows.T_base_flange[keep],
            image_suffix=suffix,
            provenance={"import": source or {"poses": str(poses), "rotation": rows.convention,
                                             "units": rows.units, "target": str(target),
                                             "images": cam.pattern}},
        )  # fmt: skip
        write_pose_dataset(ds)
        return ds
