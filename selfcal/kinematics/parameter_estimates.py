"""What the kinematic estimators' results share: the minimal parameters estimated or held.

:class:`~selfcal.calibration.identify.IdentificationResult` (camera poses) and
:class:`~selfcal.calibration.tracker.identify.TrackerResult` (tracker measurements) both estimate the minimal
MCPC parameters of a chain, hold the ones the data cannot identify and report a covariance and a
rank; :class:`ParameterEstimates` holds those fields and the views on them, once.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["ParameterEstimates"]


@dataclass(frozen=True)
class ParameterEstimates:
    """Minimal parameters with their estimates (SI: rad, m).

    Attributes:
        names: minimal parameter names, eq. 10 order (``alpha0 .. ly5, lz5``).
        values: the value of every minimal parameter (rad, m); held ones at their start.
        std: standard deviations (rad, m); ``nan`` for held parameters.
        estimated: boolean mask of the estimated parameters; ``held = ~estimated``.
        held_reason: name -> why it was held (``"explicit"``, ``"unidentifiable from this
            data"``, ...).
        covariance: (p, p) covariance of the estimated parameters (order of ``names[estimated]``).
        rank: numerical rank of the considered (not explicitly held) parameters' Jacobian;
            n_params: their number.
    """

    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    estimated: np.ndarray
    held_reason: dict[str, str]
    covariance: np.ndarray
    rank: int
    n_params: int

    @property
    def identifiable(self) -> tuple[str, ...]:
        """Names of the estimated parameters."""
        return tuple(n for n, e in zip(self.names, self.estimated) if e)

    @property
    def held(self) -> tuple[str, ...]:
        """Names of the parameters held at their starting (nominal) values."""
        return tuple(n for n, e in zip(self.names, self.estimated) if not e)

    def rows(self) -> Iterator[tuple[str, float, float, bool, str | None]]:
        """``(name, value, std, estimated, why held or None)`` of every parameter (rad, m)."""
        for nm, v, s, e in zip(self.names, self.values, self.std, self.estimated):
            yield nm, float(v), float(s), bool(e), self.held_reason.get(nm)

    def table(self, is_angle: Sequence[bool] | np.ndarray) -> list[str]:
        """One line a parameter: name, value +- std in deg (``is_angle``) or mm, why held."""
        lines = []
        for (nm, v, s, _, why), a in zip(self.rows(), is_angle):
            k, u = (np.degrees(1.0), "deg") if a else (1000.0, "mm")
            note = f"  held: {why}" if why is not None else ""
            lines.append(f"{nm:>7s} {v * k:12.5f} +- {s * k:9.5f} {u}{note}")
        return lines
