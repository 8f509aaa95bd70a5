"""The run-to-run spread of a calibrated tool point, shared by the routes (issue #29).

Would another set of postures of the same kind give the same tool point? Each route refits on
resamples of its postures (the tracker: a bootstrap over its rows,
:mod:`selfcal.calibration.tracker.spread`; the board: a delete-a-configuration jackknife over its
cross-validation folds, :mod:`selfcal.calibration.board.spread`) and predicts the refits' tool
points at the workspace sample's joint vectors and at the calibration postures. The spread at a
joint vector is an RMS distance (mm); this module holds the block they write
(``calibration.json`` ``accuracy.spread``: its largest and median value per region) and the one
line a report prints of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["BOOTSTRAP", "JACKKNIFE", "REGIONS", "Spread", "region_spread", "spread_line"]

REGIONS = ("inside", "edge", "workspace", "calibration_postures")
"""The regions of the workspace sample (:mod:`selfcal.kinematics.tool_error`) and the postures."""
BOOTSTRAP = "bootstrap"
JACKKNIFE = "jackknife"


@dataclass(frozen=True)
class Spread:
    """A run-to-run spread: ``resamplings`` refits used, ``failed`` not, and per region
    (:data:`REGIONS`) the largest and the median spread (mm RMS) of its joint vectors (absent
    for an empty region); ``method`` :data:`BOOTSTRAP` or :data:`JACKKNIFE`, ``what`` the
    sentence saying what was resampled and how the spread is computed; ``extra`` further keys of
    the block (a route's own)."""

    resamplings: int
    failed: int
    regions: dict
    what: str
    method: str = BOOTSTRAP
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The ``spread`` entry of the ``accuracy`` block (mm)."""
        return {
            "what": self.what,
            "method": self.method,
            "resamplings": self.resamplings,
            "failed": self.failed,
            "regions": self.regions,
            **self.extra,
        }


def region_spread(squared: dict[str, np.ndarray]) -> dict:
    """Per region of :data:`REGIONS` present in ``squared`` (the squared spread, m^2, of each
    of its joint vectors) the largest and the median spread (mm)."""
    out = {}
    for k in REGIONS:
        if k in squared and len(squared[k]):
            s = np.sqrt(np.asarray(squared[k], dtype=float)) * 1e3
            out[k] = {"spread_mm_max": float(s.max()), "spread_mm_median": float(np.median(s))}
    return out


def spread_line(spread: dict) -> str:
    """One line on a :meth:`Spread.to_json` block (a block without ``method``, written before
    it, is a bootstrap's)."""
    r = spread["regions"]
    if spread.get("method", BOOTSTRAP) == JACKKNIFE:
        how = (f"a delete-a-configuration jackknife over the {spread['resamplings']} "
               "cross-validation folds")  # fmt: skip
    else:
        how = f"{spread['resamplings']} bootstrap resamplings of the rows"
    text = (
        f"run-to-run spread over {how}: "
        f"{r['inside']['spread_mm_max']:.3f} mm RMS at most inside the calibrated region"
    )
    if "edge" in r:
        text += f", {r['edge']['spread_mm_max']:.3f} mm at its edge"
    return text
