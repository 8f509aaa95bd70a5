"""The seed paper's tables checked against each other: :func:`paper_inconsistencies`.

Its tables (``selfcal.config.paper_data``) are kept as printed; where two disagree, one holds a typo.
``selfcal paper`` lists what is found (``paper_typos.md``), never using it as truth.
"""

from __future__ import annotations

import numpy as np

from selfcal.config.paper_data import AXES, PAPER_TABLE_III_MM, PAPER_TABLE_IV, TABLE_II_MM

__all__ = ["paper_inconsistencies"]


def paper_inconsistencies(tol_mm: float = 0.005) -> list[dict]:
    """Disagreements inside the paper's own tables (a typo somewhere in each).

    Checks, per position and axis: Table IV "desired" against Table II, Table IV "measured"
    against Table III, and Table IV's printed error against its measured - desired (value and
    sign). Returns one dict per finding: ``{position, axis, kind, printed, expected, note}``.
    """
    out = []
    des, mea, err = (PAPER_TABLE_IV[k] for k in ("desired_mm", "measured_mm", "error_mm"))
    for i in range(5):
        for k, ax in enumerate(AXES):
            where = {"position": i + 1, "axis": f"p_{ax}"}
            if abs(des[i, k] - TABLE_II_MM[i, k]) > tol_mm:
                out.append(
                    {
                        **where,
                        "kind": "Table IV desired != Table II",
                        "printed": float(des[i, k]),
                        "expected": float(TABLE_II_MM[i, k]),
                        "note": "",
                    }
                )
            if abs(mea[i, k] - PAPER_TABLE_III_MM[i, k]) > tol_mm:
                out.append(
                    {
                        **where,
                        "kind": "Table IV measured != Table III measured",
                        "printed": float(mea[i, k]),
                        "expected": float(PAPER_TABLE_III_MM[i, k]),
                        "note": (
                            "Table IV's printed error matches Table IV's measured value"
                            if abs(mea[i, k] - des[i, k] - err[i, k]) <= tol_mm
                            else "the printed error matches neither"
                        ),
                    }
                )
            diff = mea[i, k] - des[i, k]
            if abs(diff - err[i, k]) > tol_mm:
                sign = "sign disagrees" if np.sign(diff) != np.sign(err[i, k]) else "same sign"
                out.append(
                    {
                        **where,
                        "kind": "Table IV error != measured - desired",
                        "printed": float(err[i, k]),
                        "expected": round(float(diff), 2),
                        "note": sign,
                    }
                )
    return out
