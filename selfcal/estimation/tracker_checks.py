"""Do tracker measurements look like the arm they claim to measure? Checked before identification.

A tracker file can be read without an error and still be unusable: every position on one line
(a column copied over the others, a tracker that followed one axis), or positions in metres
under ``x_mm`` headers (a robot 1000 times too small). The identification fits either
"successfully" -- before, 125.8 mm and 0.00013 mm RMS with exit 0 -- because the tracker frame,
the tool point and the link lengths absorb what they can. The nominal arm knows the geometry:
its flange at the same joint readings spreads over a volume of the arm's size.

:func:`check_tracker_geometry` compares the measured positions with the nominal flange's at the
same joints: their spread (RMS distance from the centroid) must not be smaller by more than a
factor of :data:`SCALE_FACTOR`, nor larger by that factor and a tool's length (the tool point is
unknown, so only the order of magnitude is checked; the synthetic cases of
``selfcal.benchmarks.tracker.sim`` read 1.04 to 1.12 on three arms), and the measured positions must
not lie on a line when the nominal flange's do not (second principal spread below
:data:`LINE_RATIO` of the first, where the nominal's is above ten times that). Distances
(ball bar) are checked the same way against the nominal flange distances.
"""

from __future__ import annotations

import numpy as np

from selfcal.errors import InputError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel

__all__ = ["SCALE_FACTOR", "TOOL_M", "LINE_RATIO", "TrackerGeometryError", "check_tracker_geometry"]

SCALE_FACTOR = 3.0
"""How far the measured spread may be from the nominal flange's (either way): metres as mm is
1000, centimetres 10, inches 25.4."""
TOOL_M = 1.0
"""A tool point may move this much (m RMS) more than the flange (a long tool turned by the
wrist) before a larger spread is blamed on the unit."""
LINE_RATIO = 0.01
"""Second principal spread over the first below which positions lie on a line."""
_UNITS = (("metres", 1e-3), ("centimetres", 1e-1), ("inches", 1 / 25.4))


class TrackerGeometryError(InputError):
    """Tracker measurements whose geometry does not match the arm (exit code 2)."""


def _spreads(p: np.ndarray) -> np.ndarray:
    """Principal RMS spreads (3,) of the points ``p`` (m, 3) about their centroid, largest
    first."""
    return np.linalg.svd(p - p.mean(axis=0), compute_uv=False) / np.sqrt(len(p))


def _unit_hint(factor: float) -> str:
    for name, f in _UNITS:
        if abs(np.log(factor / f)) < np.log(1.5):
            return f": these look like {name}"
    return ""


def _off_scale(got_m: float, nominal_m: float) -> bool:
    """Whether a measured spread ``got_m`` is off the nominal flange's ``nominal_m`` by more than a
    tool can explain: below 1 / :data:`SCALE_FACTOR` of it, or above :data:`SCALE_FACTOR` times
    it and :data:`TOOL_M` more (a tool turned by the wrist moves far more than the flange)."""
    return got_m < nominal_m / SCALE_FACTOR or (
        got_m > SCALE_FACTOR * nominal_m and got_m - nominal_m > TOOL_M
    )


def check_tracker_geometry(
    model: MCPCModel, meas: TrackerMeasurements, where: str, distances: str | None = None
) -> None:
    """Refuse measurements whose spread or shape does not match the nominal arm (module
    docstring).

    Args:
        model: the nominal chain (tool = flange), SI.
        meas: the measurements (SI, tracker frame).
        where: the measurements file (for messages); ``distances``: the distances file.

    Raises:
        TrackerGeometryError: positions on a line, or spread by another factor than the arm's
            (named with both spreads in mm and the likely unit).
    """
    if meas.m >= 3:
        got = _spreads(meas.xyz)
        nom = _spreads(fk_tool(model, meas.q)[:, :3, 3])
        if nom[0] > 0 and got[0] > 0:
            factor = float(np.linalg.norm(got) / np.linalg.norm(nom))
            if _off_scale(float(np.linalg.norm(got)), float(np.linalg.norm(nom))):
                raise TrackerGeometryError(
                    f"{where}: the measured positions (x_mm, y_mm, z_mm) spread "
                    f"{np.linalg.norm(got) * 1e3:.4g} mm RMS about their centroid, the nominal robot's flange "
                    f"at the same joints {np.linalg.norm(nom) * 1e3:.4g} mm: {factor:.3g} times "
                    f"{'smaller' if factor < 1 else 'larger'}{_unit_hint(factor)}",
                    fix="write the positions in millimetres (metres x 1000), or give the robot "
                    "that was measured (--robot)",
                )
        if got[1] < LINE_RATIO * got[0] and nom[1] > 10 * LINE_RATIO * nom[0]:
            raise TrackerGeometryError(
                f"{where}: every measured position lies on one line (spread "
                f"{got[1] * 1e3:.3g} mm across it against {got[0] * 1e3:.4g} mm along it), "
                f"while the nominal robot's flange at the same joints spreads "
                f"{nom[1] * 1e3:.4g} mm across its main direction",
                fix="check the x_mm, y_mm, z_mm columns (a column copied over another, or the "
                "tracker's export of one axis)",
            )
    if meas.k >= 1 and meas.d is not None and meas.q_a is not None and meas.q_b is not None:
        pa, pb = fk_tool(model, meas.q_a)[:, :3, 3], fk_tool(model, meas.q_b)[:, :3, 3]
        nom_d = float(np.sqrt(np.mean(np.sum((pa - pb) ** 2, axis=1))))
        got_d = float(np.sqrt(np.mean(meas.d**2)))
        if nom_d > 0 and _off_scale(got_d, nom_d):
            factor = got_d / nom_d
            raise TrackerGeometryError(
                f"{distances or where}: the distances (d_mm) are {got_d * 1e3:.4g} mm RMS, the "
                f"nominal robot's flange moves {nom_d * 1e3:.4g} mm RMS between the same joint "
                f"readings: {factor:.3g} times {'smaller' if factor < 1 else 'larger'}"
                f"{_unit_hint(factor)}",
                fix="write the distances in millimetres, or give the robot that was measured",
            )
