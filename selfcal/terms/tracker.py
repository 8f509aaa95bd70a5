"""The tracker term: tracker positions, poses and distances estimated with the images.

A lab that has both camera images of the robot's postures (the dataset) and tracker readings of
the same robot (tool-point positions, tool poses or ball-bar distances, each row with its own
joint readings; :mod:`selfcal.io.tracker`) gets one estimate (``selfcal calibrate DIR --tracker
FILE``): the tracker's residual blocks (:func:`selfcal.estimation.tracker.tracker_terms`) join the
one-step refinement over the images (:func:`selfcal.calibration.field.joint_refine.joint_refine`),
which estimates the tracker frame and the tool point with the kinematics. :class:`TrackerTerm` is
the term (:mod:`selfcal.terms.base`); :func:`tracker_source` is what ``calibration.json`` records of
it (:class:`selfcal.io.calibration_tracker.TrackerSource`, section ``tracker``). Units: SI inside,
mm / deg in the record.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from selfcal.estimation.tracker import TrackerMeasurements, tracker_report, tracker_terms
from selfcal.estimation.tracker_checks import check_tracker_geometry
from selfcal.io.calibration_blocks import matrix
from selfcal.io.calibration_tracker import TrackerSource
from selfcal.io.tracker import Table, read_distances, read_measurements
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.definition import RobotDef
from selfcal.terms.base import TermBlocks, TermContext, TermOption, TermReport, TermSolution
from selfcal.transforms import inv_pose

__all__ = [
    "TrackerTerm",
    "tracker_source",
    "read_tracker_files",
    "DEFAULT_SIGMA_M",
    "DEFAULT_SIGMA_RAD",
]

DEFAULT_SIGMA_M = 1e-4
"""Default tracker noise per coordinate (0.1 mm: a laser tracker's, as ``selfcal identify``)."""
DEFAULT_SIGMA_RAD = float(np.radians(0.01))
"""Default noise of a measured tool orientation (0.01 deg, as ``selfcal identify``)."""


def read_tracker_files(
    measurements: str | Path,
    distances: str | Path | None,
    robot: RobotDef,
    units: str,
    *,
    guess: bool = True,
) -> tuple[TrackerMeasurements, Table]:
    """``(TrackerMeasurements, Table)``: the measurements file (positions or poses, tracker
    frame) and, when given, the distances file of ``robot`` (:mod:`selfcal.io.tracker`, joints
    in ``units``), SI, their geometry checked against the nominal arm
    (:mod:`selfcal.estimation.tracker_checks`). ``guess=False``: skip the check that degrees
    look like radians.

    Raises:
        InputError: a file that cannot be read (named with row and column), or measurements
            whose geometry does not fit the arm (off by a unit's factor: said).
    """
    meas, table = read_measurements(measurements, robot, units, guess=guess)
    if distances:
        qa, qb, d = read_distances(distances, robot, units, guess=guess)
        meas = TrackerMeasurements(meas.q, meas.xyz, meas.R, qa, qb, d)
    check_tracker_geometry(
        nominal_mcpc(robot), meas, str(measurements), None if distances is None else str(distances)
    )
    return meas, table


@dataclass(frozen=True)
class TrackerTerm:
    """Tracker data to estimate with the images (a :class:`selfcal.terms.base.Term`).

    Attributes:
        measurements: positions / poses / distances in SI units (joints rad, m).
        joint_units: the units the files declared (``deg`` or ``rad``), recorded.
        file, distances_file: where they came from (recorded; None when not from a file).
        sigma_m, sigma_rad: the noise of a coordinate (m) and of an orientation (rad).
    """

    measurements: TrackerMeasurements
    joint_units: str = "deg"
    file: str | None = None
    distances_file: str | None = None
    sigma_m: float = DEFAULT_SIGMA_M
    sigma_rad: float = DEFAULT_SIGMA_RAD

    kind = "tracker"
    OPTIONS: ClassVar[tuple[TermOption, ...]] = (
        TermOption("joint_units", "the units of the files' joints (deg: degrees and prismatic "
                   "mm; rad: radians and m); default the command's --joint-units",
                   required=True, choices=("deg", "rad")),
        TermOption("distances", "ball-bar distances too (a_j1..a_jn,b_j1..b_jn,d_mm)",
                   path=True),
        TermOption("sigma_mm", "position / distance noise per coordinate", "mm", "0.1"),
        TermOption("sigma_deg", "orientation noise of tool poses", "deg", "0.01"),
    )  # fmt: skip
    """The options of :meth:`from_file` (``selfcal calibrate --term tracker=FILE,NAME=VALUE``)."""

    @classmethod
    def from_file(
        cls, path: str | Path, robot: RobotDef, options: Mapping[str, Any]
    ) -> TrackerTerm:
        """The measurements in ``path`` (docs/tracker.md) with the values of :data:`OPTIONS`,
        read and checked as ``selfcal identify`` reads them (:func:`read_tracker_files`)."""
        dist = options.get("distances")
        units = options["joint_units"]
        meas, _ = read_tracker_files(path, dist, robot, units)
        return cls(meas, joint_units=units, file=str(path),
                   distances_file=None if dist is None else str(dist),
                   sigma_m=1e-3 * float(options["sigma_mm"]),
                   sigma_rad=float(np.radians(float(options["sigma_deg"]))))  # fmt: skip

    def build(self, context: TermContext) -> TermBlocks:
        """The position or pose block and the distance block over the chain of ``context``, with
        the tracker frame, tool point and tool frame as new unknowns
        (:func:`selfcal.estimation.tracker.tracker_terms`)."""
        scale = (self.sigma_m / context.unit_sigma, self.sigma_rad / context.unit_sigma)
        blocks, params = tracker_terms(
            self.measurements, context.model, context.free_idx, context.block, *scale
        )
        return TermBlocks(tuple(blocks), tuple(params), state=scale[0])

    def report(self, blocks: TermBlocks, solution: TermSolution) -> TermReport:
        """The fit per block and the estimated frames (diagnostics, SI:
        :func:`selfcal.estimation.tracker.tracker_report`) and their record."""
        diag = tracker_report(list(blocks.residuals), list(blocks.parameters), solution.values,
                              solution.residuals, blocks.state)  # fmt: skip
        return TermReport(diag, tracker_source(self, diag, solution.model, solution.model_gauge))


def kinds(meas: TrackerMeasurements) -> tuple[str, ...]:
    """What ``meas`` holds: ``positions`` or ``poses``, and ``distances``."""
    out = []
    if meas.m:
        out.append("poses" if meas.R is not None else "positions")
    if meas.k:
        out.append("distances")
    return tuple(out)


def tracker_source(
    inp: TrackerTerm, diagnostics: dict, model: MCPCModel, model_gauge: MCPCModel
) -> TrackerSource:
    """The ``calibration.json`` record of ``inp`` estimated by the joint refinement whose
    ``diagnostics`` (:func:`selfcal.estimation.tracker.tracker_report`'s keys), final ``model``
    (world = the reference left camera) and ``model_gauge`` (the adjustment's world, where the
    tracker frame was estimated) are given."""
    meas = inp.measurements
    rms = {
        k[len("tracker_") : -len("_rms_m")]: 1e3 * float(v)
        for k, v in diagnostics.items()
        if k.startswith("tracker_") and k.endswith("_rms_m")
    }
    T_tracker_world = None
    if diagnostics.get("tracker_frame") is not None:
        # the same chain in both worlds: T_gauge_world = T_gauge_tool(q) T_world_tool(q)^-1
        q0 = meas.q[:1]
        T_gauge_world = fk_tool(model_gauge, q0)[0] @ inv_pose(fk_tool(model, q0)[0])
        T_tracker_world = matrix(np.asarray(diagnostics["tracker_frame"]) @ T_gauge_world)
    point = diagnostics.get("tool_point")
    tool = diagnostics.get("tool_frame")
    return TrackerSource(
        file=inp.file,
        distances_file=inp.distances_file,
        joint_units=inp.joint_units,
        kinds=kinds(meas),
        rows=meas.m,
        distances=meas.k,
        sigma_mm=1e3 * inp.sigma_m,
        sigma_deg=float(np.degrees(inp.sigma_rad)),
        rms_mm=rms,
        T_tracker_world_m=T_tracker_world,
        tool_point_mm=None if point is None else tuple(1e3 * np.asarray(point, dtype=float)),
        T_cam_tool_m=None if tool is None else matrix(np.asarray(tool)),
    )
