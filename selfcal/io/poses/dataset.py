"""A pose dataset: images of one camera and the robot's flange poses (no joint readings).

Layout of ``DIR``::

    dataset.json   format "scorbot-selfcal-pose-dataset": the setup (``eye-in-hand``: the camera
                   on the flange, the board static; ``eye-to-hand``: the camera static, the board
                   on the flange), the camera (name, resolution, model, free parameters), the
                   target (the board's target TOML keys, mm) and the provenance (files read)
    poses.csv      index, x_mm, y_mm, z_mm, qx, qy, qz, qw: base -> flange of every frame
    frames/NNNN_CAMERA.EXT   the frame's image
    sources.csv    index, camera, source: where every image came from

Nothing here is truth: the poses are the robot's reports.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.choices import SETUPS
from selfcal.errors import InputError
from selfcal.io.atomic import write_text_atomic
from selfcal.io.jsonfile import SCHEMA_KEY, check_header, load_json, write_json_atomic
from selfcal.transforms import make_pose

__all__ = [
    "POSE_FORMAT",
    "SETUPS",
    "PoseDataset",
    "PoseDatasetError",
    "is_pose_dataset",
    "write_pose_dataset",
]

POSE_FORMAT = "scorbot-selfcal-pose-dataset"
_FIX = "import it again with `selfcal import --poses FILE ...` (docs/handeye.md)"
_HEADER = ["index", "x_mm", "y_mm", "z_mm", "qx", "qy", "qz", "qw"]


class PoseDatasetError(InputError):
    """A pose dataset folder that is missing, damaged or inconsistent."""


def is_pose_dataset(root: str | Path) -> bool:
    """Whether ``root/dataset.json`` declares a pose dataset."""
    meta = Path(root) / "dataset.json"
    if not meta.is_file():
        return False
    try:
        return load_json(meta, fix=_FIX).get("format") == POSE_FORMAT
    except InputError:
        return False


@dataclass(frozen=True)
class PoseDataset:
    """A pose dataset (module docstring): ``setup`` (:data:`SETUPS`), ``camera`` name,
    ``resolution`` (W, H) px, camera ``model`` and ``free`` parameters (OpenCV names),
    ``board`` the target TOML document (mm), ``T_base_flange`` (n, 4, 4) m, ``image_suffix``,
    ``provenance``; ``root`` the folder."""

    root: Path
    setup: str
    camera: str
    resolution: tuple[int, int]
    model: str
    free: tuple[str, ...]
    board: dict
    T_base_flange: np.ndarray
    image_suffix: str = ".png"
    provenance: dict = field(default_factory=dict)

    def image_path(self, index: int) -> Path:
        """The image of frame ``index``."""
        return self.root / "frames" / f"{index:04d}_{self.camera}{self.image_suffix}"

    @classmethod
    def open(cls, root: str | Path) -> PoseDataset:
        """Read the pose dataset in ``root``.

        Raises:
            PoseDatasetError: no or a damaged ``dataset.json`` or ``poses.csv`` (naming the
                file, line and key).
        """
        root = Path(root)
        meta = root / "dataset.json"
        doc = load_json(meta, fix=_FIX, error=PoseDatasetError)
        check_header(doc, str(meta), fmt=POSE_FORMAT, version=1, fix=_FIX, error=PoseDatasetError)
        try:
            cam = doc["camera"]
            setup = str(doc["setup"])
            info = dict(setup=setup, camera=str(cam["name"]),
                        resolution=(int(cam["resolution"][0]), int(cam["resolution"][1])),
                        model=str(cam["model"]), free=tuple(str(f) for f in cam["free"]),
                        board=dict(doc["target"]), image_suffix=str(doc.get("image_suffix", ".png")),
                        provenance=dict(doc.get("provenance", {})))  # fmt: skip
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise PoseDatasetError(f"{meta}: missing or malformed key {exc}", fix=_FIX) from None
        if setup not in SETUPS:
            raise PoseDatasetError(f"{meta}: setup {setup!r}", fix=f"use one of {list(SETUPS)}")
        T = _read_poses_csv(root / "poses.csv")
        return cls(root=root, T_base_flange=T, **info)  # type: ignore[arg-type]

    def to_json(self) -> dict:
        """The ``dataset.json`` document."""
        return {
            "format": POSE_FORMAT,
            SCHEMA_KEY: 1,
            "setup": self.setup,
            "poses": "base -> flange (poses.csv: mm, quaternion xyzw)",
            "camera": {
                "name": self.camera,
                "resolution": list(self.resolution),
                "model": self.model,
                "free": list(self.free),
            },  # fmt: skip
            "target": self.board,
            "image_suffix": self.image_suffix,
            "provenance": self.provenance,
        }


def _read_poses_csv(path: Path) -> np.ndarray:
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise PoseDatasetError(f"{path}: cannot be read ({exc.strerror})", fix=_FIX) from None
    if not rows or [h.strip() for h in rows[0]] != _HEADER:
        raise PoseDatasetError(f"{path}: header is not {','.join(_HEADER)}", fix=_FIX)
    vals: list[list[float]] = []
    for line, r in enumerate(rows[1:], start=2):
        try:
            v = [float(x) for x in r]
        except ValueError:
            v = []
        if len(v) != len(_HEADER) or int(v[0]) != len(vals) or not np.isfinite(v).all():
            raise PoseDatasetError(f"{path}, line {line}: not a pose row of frame {len(vals)}",
                                   fix=_FIX)  # fmt: skip
        vals.append(v[1:])
    if not vals:
        raise PoseDatasetError(f"{path}: no poses", fix=_FIX)
    a = np.array(vals)
    return make_pose(Rotation.from_quat(a[:, 3:]).as_matrix(), a[:, :3] / 1000.0)


def write_pose_dataset(ds: PoseDataset) -> None:
    """Write ``dataset.json`` and ``poses.csv`` of ``ds`` into ``ds.root`` (the frames are
    the caller's)."""
    ds.root.mkdir(parents=True, exist_ok=True)
    q = Rotation.from_matrix(ds.T_base_flange[:, :3, :3]).as_quat()
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_HEADER)
    for k, (T, qk) in enumerate(zip(ds.T_base_flange, q, strict=True)):
        w.writerow([k] + [f"{v:.9f}" for v in T[:3, 3] * 1000.0] + [f"{v:.12f}" for v in qk])
    write_text_atomic(ds.root / "poses.csv", buf.getvalue())
    write_json_atomic(ds.root / "dataset.json", ds.to_json())
