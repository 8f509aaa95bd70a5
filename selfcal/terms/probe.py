"""The touch-probe term: a probe tip on the tool touches known 3-D points.

A probe (a ball or a pointed stylus) fixed on the robot's tool touches points whose positions are
known in a fixture's frame (the sockets of a calibration artefact measured on a CMM, the corners
of a jig). Each touch is one row: the joint readings and the point touched. Per touch, 3 residual
rows in the problem's unit (:class:`selfcal.terms.base.TermContext`)::

    r = (T_fixture_world FK(q) tip - p) / sigma * unit_sigma

with ``FK(q)`` the chain being calibrated (world and tool of the problem), ``tip`` the probe tip
in the tool frame and ``p`` the touched point in the fixture frame (m inside; mm at the edges:
the file's ``x_mm, y_mm, z_mm`` and the section's ``_mm`` keys). The Jacobian is the tool point's
(:meth:`selfcal.estimation.tracker.ChainLayout.points`). Unknowns the term adds: the fixture frame
(block ``probe_fixture``, ``[w, v]`` around a closed-form start,
:func:`selfcal.estimation.tracker_start.initial_placement`) unless ``T_fixture_world`` is given,
and the tip in the tool frame (block ``probe_tip``, m) unless ``tip_m`` is given.

The file (:meth:`ProbeTerm.read`): one row per touch, ``j1..jn, x_mm, y_mm, z_mm``, the point's
known coordinates in the fixture frame; the joints in the units the caller names. It is read by
the reader of tracker positions (:func:`selfcal.io.tracker.read_measurements`: a bad entry is
named by file, row and column). ``calibration.json`` records the term as the section ``probe``
(:class:`ProbeSection`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from selfcal.errors import InputError
from selfcal.estimation.tracker import ChainLayout
from selfcal.estimation.tracker_start import initial_placement
from selfcal.io.calibration_blocks import matrix
from selfcal.io.jsonblock import JsonBlock
from selfcal.io.tracker import read_measurements
from selfcal.kinematics.forward import fk_tool
from selfcal.solver import Evaluation, JacobianPiece, Loss, ParameterBlock
from selfcal.terms.base import TermBlocks, TermContext, TermOption, TermReport, TermSolution
from selfcal.transforms import inv_pose

__all__ = ["ProbeTerm", "ProbeSection", "ProbeBlock", "DEFAULT_SIGMA_M"]

DEFAULT_SIGMA_M = 2e-5
"""Default noise of a touch per coordinate (0.02 mm: a touch probe's repeatability)."""

PROBE_NOTE = (
    "touch-probe points estimated with the dataset's images: tip_mm is the probe tip in the "
    "calibrated chain's tool frame (mcpc's tool: the left or first camera, OpenCV, or eye-to-hand "
    "the board); T_fixture_world_m places the fixture of the known points in the calibration's "
    "world frame (null: it was given); rms_mm and max_mm are the fit over the touches (3-D)"
)


@dataclass(frozen=True, eq=False)
class ProbeSection(JsonBlock):
    """``probe``: what the touch-probe term recorded (see the module docstring)."""

    kind: ClassVar[str] = "probe"

    file: str | None
    touches: int
    points: int
    sigma_mm: float
    rms_mm: float
    max_mm: float
    tip_mm: tuple[float, ...]
    T_fixture_world_m: np.ndarray | None = field(metadata={"shape": (4, 4)})
    note: str = PROBE_NOTE

    def summary(self) -> str:
        """One line for people."""
        tip = ", ".join(f"{v:.3f}" for v in self.tip_mm)
        return (
            f"probe: {self.touches} touches of {self.points} known points estimated with the "
            f"images, fit RMS {self.rms_mm:.4f} mm (max {self.max_mm:.4f}); tip ({tip}) mm"
        )


class ProbeBlock:
    """Residual rows ``(y_i - p_i) w`` (3 each): the tip ``y`` at joints ``q`` (m, n) in the
    fixture frame (``layout``'s tracker frame) against the touched points ``p`` (m, 3) m;
    ``w`` the weight (units per m)."""

    dim = 3

    def __init__(self, layout: ChainLayout, q: np.ndarray, p: np.ndarray, w: float) -> None:
        self.name = "probe"
        self.loss = Loss()
        self.layout, self.q, self.p, self.w = layout, q, p, float(w)

    def evaluate(self, values: Mapping[str, np.ndarray], jacobian: bool) -> Evaluation:
        """Residuals (m, 3) and the pieces of the chain, fixture and tip blocks."""
        y, raw = self.layout.points(values, self.q, jacobian)
        k = len(y)
        pieces = tuple(
            JacobianPiece(b, J * self.w, np.broadcast_to(c, (k, len(c)))) for b, J, c in raw
        )
        return Evaluation((y - self.p) * self.w, pieces)


@dataclass(frozen=True)
class ProbeTerm:
    """Touches of known points (a :class:`selfcal.terms.base.Term`).

    Attributes:
        q: (m, n) joint readings of the touches (rad, m).
        points: (k, 3) the known points in the fixture frame (m).
        touched: (m,) index into ``points`` of each touch.
        sigma_m: noise of a touch per coordinate (m).
        T_fixture_world: (4, 4) the fixture frame in the problem's world (m), or None: estimated.
        tip_m: (3,) the probe tip in the problem's tool frame (m), or None: estimated.
        file: where the touches came from (recorded), or None.

    Raises:
        InputError: shapes that do not fit, an index outside ``points``, non-finite numbers or a
            noise that is not positive.
    """

    q: np.ndarray
    points: np.ndarray
    touched: np.ndarray
    sigma_m: float = DEFAULT_SIGMA_M
    T_fixture_world: np.ndarray | None = None
    tip_m: np.ndarray | None = None
    file: str | None = None
    kind: ClassVar[str] = "probe"
    OPTIONS: ClassVar[tuple[TermOption, ...]] = (
        TermOption("joint_units", "the units of the file's joints (deg: degrees and prismatic "
                   "mm; rad: radians and m); default the command's --joint-units",
                   required=True, choices=("deg", "rad")),
        TermOption("sigma_mm", "noise of a touch per coordinate", "mm", "0.02"),
    )  # fmt: skip
    """The options of :meth:`from_file` (``selfcal calibrate --term probe=FILE,NAME=VALUE``)."""

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        pts = np.asarray(self.points, dtype=float).reshape(-1, 3)
        idx = np.asarray(self.touched).reshape(-1)
        if len(idx) != len(q) or not np.issubdtype(idx.dtype, np.integer):
            raise InputError(f"probe: {len(q)} joint rows need as many integer point indices")
        if idx.size and (idx.min() < 0 or idx.max() >= len(pts)):
            raise InputError(f"probe: a touch names a point outside the {len(pts)} known points")
        if not (np.isfinite(q).all() and np.isfinite(pts).all()):
            raise InputError("probe: the joints or the points hold NaN or inf")
        if not self.sigma_m > 0:
            raise InputError(f"probe: the noise must be positive, got {self.sigma_m} m")
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "touched", idx.astype(np.int64))

    @classmethod
    def read(
        cls, path: str | Path, robot, joint_units: str, sigma_m: float = DEFAULT_SIGMA_M
    ) -> ProbeTerm:
        """The touches in ``path`` (module docstring) of ``robot``, joints in ``joint_units``
        (``deg``: degrees and prismatic mm; ``rad``: rad and m).

        Raises:
            TrackerFileError: a missing column, a bad entry (named by row and column), or
                orientation columns (a touch has none).
        """
        meas, _ = read_measurements(path, robot, joint_units)
        if meas.R is not None:
            raise InputError(
                f"{path}: a touch has no orientation, but the file has qw, qx, qy, qz columns",
                fix="give j1..jn, x_mm, y_mm, z_mm per touch (tool poses are tracker data)",
            )
        points, touched = np.unique(meas.xyz, axis=0, return_inverse=True)
        return cls(meas.q, points, touched.reshape(-1), sigma_m, file=str(path))

    @classmethod
    def from_file(cls, path: str | Path, robot, options: Mapping[str, Any]) -> ProbeTerm:
        """The touches in ``path`` with the values of :data:`OPTIONS` (``sigma_mm`` in mm),
        as :meth:`read` reads them."""
        return cls.read(path, robot, options["joint_units"], 1e-3 * float(options["sigma_mm"]))

    # ------------------------------------------------------------------ the term
    def build(self, context: TermContext) -> TermBlocks:
        """The probe block over the chain of ``context``; the fixture frame and the tip as new
        unknowns when they are not given."""
        if self.q.shape[1] != context.model.n:
            raise InputError(
                f"probe: the touches have {self.q.shape[1]} joints, the robot {context.model.n}"
            )
        p = self.points[self.touched]
        frame0, s0 = initial_placement(context.model, self.q, p)
        if self.T_fixture_world is not None:  # known: the points in the problem's world
            T = inv_pose(np.asarray(self.T_fixture_world, dtype=float))
            p = p @ T[:3, :3].T + T[:3, 3]
        params = []
        if self.T_fixture_world is None:
            params.append(ParameterBlock("probe_fixture", np.zeros(6)))
        if self.tip_m is None:
            params.append(ParameterBlock("probe_tip", s0))
        layout = ChainLayout(
            context.model,
            context.block,
            context.coords(),
            frame="probe_fixture" if self.T_fixture_world is None else None,
            frame0=frame0,
            point="probe_tip" if self.tip_m is None else None,
            point0=s0 if self.tip_m is None else np.asarray(self.tip_m, dtype=float),
        )
        block = ProbeBlock(layout, self.q, p, context.unit_sigma / self.sigma_m)
        return TermBlocks((block,), tuple(params), state=block)

    def report(self, blocks: TermBlocks, solution: TermSolution) -> TermReport:
        """The fit (3-D RMS and maximum over the touches), the tip and the fixture frame."""
        block: ProbeBlock = blocks.state
        e = np.linalg.norm(solution.residuals[block.name], axis=1) / block.w  # m
        lay = block.layout
        tip = lay.tool_point(solution.values)
        T_fw = None
        if lay.frame is not None:
            # the same chain in both worlds: T_gauge_world = T_gauge_tool(q) T_world_tool(q)^-1
            q0 = self.q[:1]
            T_gw = fk_tool(solution.model_gauge, q0)[0] @ inv_pose(fk_tool(solution.model, q0)[0])
            T_fw = lay.tracker_frame(solution.values) @ T_gw
        rms = float(np.sqrt(np.mean(e**2)))
        diag = {"probe_rms_m": rms, "probe_tip": tip.tolist()}
        if T_fw is not None:
            diag["probe_fixture"] = T_fw.tolist()
        section = ProbeSection(
            file=self.file,
            touches=len(self.q),
            points=len(self.points),
            sigma_mm=1e3 * self.sigma_m,
            rms_mm=1e3 * rms,
            max_mm=1e3 * float(e.max()),
            tip_mm=tuple(1e3 * np.asarray(tip, dtype=float)),
            T_fixture_world_m=None if T_fw is None else matrix(T_fw),
        )
        return TermReport(diag, section)
