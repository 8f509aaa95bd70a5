"""The run-to-run spread of a calibrated tool point, shared by the routes (issue #29).

Would another set of postures of the same kind give the same tool point? Each route refits on
resamples of its postures (the tracker: a bootstrap over its rows,
:mod:`selfcal.calibration.tracker.spread`; the board: a delete-a-fold jackknife over its
cross-validation folds, :mod:`selfcal.calibration.board.spread`) and predicts the refits' tool
points at the workspace sample's joint vectors and at the calibration postures. The spread at a
joint vector is an RMS distance (mm); this module holds the block they write
(``calibration.json`` ``accuracy.spread``: its largest and median value per region) and the one
line a report prints of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from selfcal.kinematics.tool_error import WorkspaceSample

__all__ = [
    "BOOTSTRAP",
    "JACKKNIFE",
    "REGIONS",
    "Spread",
    "SpreadPoints",
    "region_spread",
    "spread_line",
]

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


@dataclass(frozen=True, eq=False)
class SpreadPoints:
    """Where a spread is evaluated: per region of :data:`selfcal.calibration.spread.REGIONS`
    the joint vectors (k, n) rad / m (``qs``), and the tool point, ``T_tool_point`` the flange
    in the chain's tool frame (4, 4)."""

    qs: dict[str, np.ndarray]
    T_tool_point: np.ndarray

    @classmethod
    def of(cls, sample: WorkspaceSample, q_cal: np.ndarray,
           T_tool_point: np.ndarray) -> SpreadPoints:  # fmt: skip
        """The workspace ``sample``'s regions and the calibration postures ``q_cal``."""
        qs = {name: np.asarray(getattr(sample, name), dtype=float) for name in REGIONS[:3]}
        qs["calibration_postures"] = np.asarray(q_cal, dtype=float)
        return cls({k: v for k, v in qs.items() if len(v)}, np.asarray(T_tool_point, float))


def region_spread(squared: dict[str, np.ndarray]) -> dict:
    """Per region of :data:`REGIONS` present in ``squared`` (the squared spread, m^2, of each
    of its joint vectors) the largest, the median, the RMS over the region and the 95th
    percentile of the spread (mm)."""
    out = {}
    for k in REGIONS:
        if k in squared and len(squared[k]):
            sq = np.asarray(squared[k], dtype=float)
            s = np.sqrt(sq) * 1e3
            out[k] = {
                "spread_mm_max": float(s.max()),
                "spread_mm_median": float(np.median(s)),
                "spread_mm_rms": float(np.sqrt(sq.mean()) * 1e3),
                "spread_mm_p95": float(np.percentile(s, 95)),
            }
    return out


def spread_line(spread: dict) -> str:
    """One line on a :meth:`Spread.to_json` block (a block without ``method``, written before
    it, is a bootstrap's of rows): how it was resampled, the largest spread inside the
    calibrated region and at its edge, and the refits that failed."""
    r = spread["regions"]
    n = spread["resamplings"]
    if spread.get("method", BOOTSTRAP) == JACKKNIFE:
        how = f"a delete-a-fold jackknife over the {n} cross-validation folds"
    elif spread.get("resampled") == "configurations":
        how = (f"{n} bootstrap refits of the {spread['configurations']} arm configurations "
               f"resampled (seed {spread['seed']}"
               + ("; model selection held" if spread.get("selection") == "held" else "")
               + ")")  # fmt: skip
    else:
        how = f"{n} bootstrap resamplings of the rows"
    failed = spread.get("failed", 0)
    tail = ""
    other = spread.get("refits_other_parameters") or 0
    if other and spread.get("selection") == "free":
        tail += f"; {other} refit(s) selected other kinematic parameters than the calibration"
    elif other:
        tail += (f"; {other} refit(s) held some of the chosen parameters at the fair nominal "
                 "(their resample could not determine them)")  # fmt: skip
    if failed:
        reasons = spread.get("failures") or []
        first = f" (first: {reasons[0]['reason']})" if reasons else ""
        tail += f"; {failed} refit(s) failed and were left out{first}"
    if "inside" not in r:
        return f"no run-to-run spread over {how}: fewer than two refits succeeded{tail}"
    text = (
        f"run-to-run spread over {how}: "
        f"{r['inside']['spread_mm_max']:.3f} mm RMS at most inside the calibrated region"
    )
    if "edge" in r:
        text += f", {r['edge']['spread_mm_max']:.3f} mm at its edge"
    return text + tail
