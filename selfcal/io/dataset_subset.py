"""A dataset folder restricted to some of its frames, without copying the images.

``subset_dataset(root, indices, out)`` makes ``out`` a dataset of the frames ``indices`` of
``root``: ``joints.csv`` holds only their rows, and every other input of ``root`` (``dataset.json``,
``frames/``, ``detections.csv``, a robot file) is a symbolic link to the original (a dataset reads
only the frames ``joints.csv`` lists). What a calibration writes (``calibration.json``, reports,
figures) is left out. The leave-some-poses-out check of ``selfcal report`` calibrates one subset
and predicts the other.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from pathlib import Path

from selfcal.io.atomic import write_text_atomic
from selfcal.io.dataset import Dataset, DatasetError

__all__ = ["subset_dataset", "OUTPUTS"]

OUTPUTS = frozenset(
    {"calibration.json", "report.json", "report.md", "table_iv.md", "validation.csv",
     "evaluation.json", "figures", "truth.json", "joints.csv"}
)  # fmt: skip
"""Entries of a dataset folder that a subset does not link (outputs, the truth, the joints)."""


def subset_dataset(root: str | Path, indices: Iterable[int], out: str | Path) -> Dataset:
    """``out`` as the dataset of ``root``'s frames ``indices`` (module docstring); returns it
    opened.

    Raises:
        DatasetError: ``root`` is not a dataset, an index is not one of its frames, or ``out``
            exists.
    """
    src = Dataset.open(root)
    keep = sorted({int(i) for i in indices})
    unknown = sorted(set(keep) - set(src.indices.tolist()))
    if unknown:
        raise DatasetError(f"{src.root}: no frame(s) {unknown[:5]} in joints.csv")
    out = Path(out)
    if out.exists():
        raise DatasetError(f"{out} exists; a dataset subset goes into a new folder")
    out.mkdir(parents=True)
    for entry in src.root.iterdir():
        if entry.name not in OUTPUTS and not entry.name.startswith("."):
            (out / entry.name).symlink_to(entry.resolve())
    rows = {int(i): q for i, q in zip(src.indices, src.joints_deg, strict=True)}
    n = src.joints_deg.shape[1]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["index"] + [f"q{j + 1}_deg" for j in range(n)])
    for i in keep:
        w.writerow([i] + [repr(float(v)) for v in rows[i]])
    write_text_atomic(out / "joints.csv", buf.getvalue())
    return Dataset.open(out)
