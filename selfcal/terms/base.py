"""What a measurement term is: its residual and parameter blocks, its report and its section.

A *term* is one kind of measurement that a calibration estimates with the rest (images of a
marker field are the route's own; tracker positions, poses and distances, touch-probe points ...).
An estimator that takes terms (:func:`selfcal.calibration.field.joint_refine.joint_refine`, the
board route's :func:`selfcal.calibration.board.refine.refine_on_board` through
:mod:`selfcal.calibration.board.terms`) hands each the :class:`TermContext` of its problem and gets back :class:`TermBlocks`: residual blocks and
new parameter blocks for :mod:`selfcal.solver`. After the solve it asks each term for its
:class:`TermReport`: diagnostics (SI) and the section that ``calibration.json`` records under the
term's ``kind`` (mm / deg for people, ``_m`` keys in metres). The estimator loops over its terms and
names none of them: a new kind is a new module and a line in :mod:`selfcal.terms.registry`.

Units: SI inside (m, rad); a term's residuals are in the problem's residual unit, i.e. its errors
divided by its own standard deviation and multiplied by :attr:`TermContext.unit_sigma` (the
standard deviation of one unit of the problem's other residuals, e.g. the corner noise in px), so
that one standard deviation of any term weighs the same.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from selfcal.errors import InputError
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.solver import ParameterBlock, ResidualBlock

__all__ = [
    "Term",
    "TermBlocks",
    "TermContext",
    "TermOption",
    "TermReport",
    "TermSection",
    "TermSolution",
    "check_terms",
    "term_blocks",
]


@dataclass(frozen=True)
class TermContext:
    """The problem a term joins.

    Attributes:
        model: the chain at the start (SI; world and tool are the problem's: for the field route
            the reconstruction frame and the left camera, OpenCV frame; for the board route the
            board frame and the first camera, eye-to-hand the first camera and the board).
        free_idx: flat MCPC parameters (``model.params.reshape(-1)`` order) that are unknowns;
            they are the first coordinates of parameter block ``block``, in this order.
        block: name of the parameter block holding them.
        unit_sigma: standard deviation of one unit of the problem's residuals (e.g. px); a term
            scales its residuals by ``unit_sigma / sigma`` (1.0: residuals in standard deviations).
    """

    model: MCPCModel
    free_idx: np.ndarray
    block: str
    unit_sigma: float = 1.0

    def coords(self) -> np.ndarray:
        """(6 (n + 1),) coordinate in :attr:`block` of every flat MCPC parameter, -1 = fixed at
        :attr:`model`'s value (the ``coords`` of :class:`selfcal.estimation.tracker.ChainLayout`)."""
        out = -np.ones(6 * (self.model.n + 1), np.int64)
        out[np.asarray(self.free_idx, dtype=np.int64)] = np.arange(len(self.free_idx))
        return out


@dataclass(frozen=True)
class TermBlocks:
    """What a term adds to a problem: residual blocks, new parameter blocks (their names unique
    in the problem) and whatever the term keeps to report on them (``state``)."""

    residuals: tuple[ResidualBlock, ...]
    parameters: tuple[ParameterBlock, ...] = ()
    state: Any = None

    def restarted(self, values: Mapping[str, np.ndarray]) -> TermBlocks:
        """The same blocks with the parameter blocks started at ``values`` (a solution's, for
        the next round of an adjustment)."""
        params = tuple(dataclasses.replace(p, value=values[p.name]) for p in self.parameters)
        return TermBlocks(self.residuals, params, self.state)


@dataclass(frozen=True)
class TermSolution:
    """The solved problem as a term sees it.

    Attributes:
        values: every parameter block's solved values (block name -> flat array).
        residuals: every residual block's solved residuals (block name -> (k, d)).
        model: the solved chain in the frame the calibration reports (SI).
        model_gauge: the solved chain in the problem's own world (where the term's parameter
            blocks were estimated); the same as ``model`` when the estimator does not re-express.
        context: the :class:`TermContext` the term was built with.
    """

    values: Mapping[str, np.ndarray]
    residuals: Mapping[str, np.ndarray]
    model: MCPCModel
    model_gauge: MCPCModel
    context: TermContext


class TermSection(Protocol):
    """A ``calibration.json`` section: written under the key ``kind``."""

    @property
    def kind(self) -> str:
        """The section's key (the term's kind)."""

    def to_json(self) -> dict:
        """The section's JSON object."""


@dataclass(frozen=True)
class TermReport:
    """What a term says after the solve: ``diagnostics`` (SI numbers and lists, merged into the
    estimator's) and its ``calibration.json`` ``section`` (None: nothing to record)."""

    diagnostics: dict = field(default_factory=dict)
    section: TermSection | None = None


@runtime_checkable
class Term(Protocol):
    """One measurement kind's data and noise (see the module docstring)."""

    kind: str

    def build(self, context: TermContext) -> TermBlocks:
        """The term's residual and parameter blocks in the problem of ``context``.

        Raises:
            InputError: data that do not fit the problem (e.g. joints of another robot).
        """

    def report(self, blocks: TermBlocks, solution: TermSolution) -> TermReport:
        """Diagnostics and ``calibration.json`` section at the solution."""


@dataclass(frozen=True)
class TermOption:
    """One option of a kind's file reader, as ``selfcal calibrate --term KIND=FILE,NAME=VALUE``
    gives it (:func:`selfcal.terms.registry.term_from_spec`): a term class lists its own in
    ``OPTIONS`` and reads its file with ``from_file(path, robot, options)``, so that a new kind
    needs no edit of the command line.

    Attributes:
        name: the option's name (``sigma_mm``: the unit in the name, as the files' columns).
        help: what it is, for people.
        unit: its unit (``mm``, ``deg``; empty for a word or a file).
        default: the value when not given, as written (None: none).
        required: the option must be given (or come from the command, e.g. ``--joint-units``).
        choices: the words it takes (empty: a positive number, or a file with ``path``).
        path: the value is a file.
    """

    name: str
    help: str
    unit: str = ""
    default: str | None = None
    required: bool = False
    choices: tuple[str, ...] = ()
    path: bool = False

    def parse(self, text: str, where: str) -> str | float:
        """The value ``text`` (a word, a file name, or a finite number > 0).

        Raises:
            InputError: a value it does not take (``where`` names the option, with the fix).
        """
        if self.path or self.choices:
            if self.choices and text not in self.choices:
                raise InputError(f"{where}: {self.name}={text} is not one of {', '.join(self.choices)}",
                                 fix=f"give {self.name}={self.choices[0]} ({self.help})")  # fmt: skip
            return text
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{where}: {self.name}={text} is not a number > 0",
                             fix=f"give {self.name} in {self.unit or 'its unit'}, e.g. "
                             f"{self.name}={self.default or 1} ({self.help})")  # fmt: skip
        return value

    def describe(self) -> str:
        """``name`` with its unit, default and help, for a list of options."""
        what = "|".join(self.choices) if self.choices else ("FILE" if self.path else self.unit)
        given = ("required" if self.required
                 else "optional" if self.default is None else f"default {self.default}")  # fmt: skip
        return f"{self.name} ({what}; {given}): {self.help}"


def check_terms(terms: Sequence[Term]) -> None:
    """Refuse two terms of one kind: their sections (and new parameter blocks) would clash.

    Raises:
        InputError: a kind given twice (named, with the fix).
    """
    kinds = [t.kind for t in terms]
    twice = sorted({k for k in kinds if kinds.count(k) > 1})
    if twice:
        raise InputError(
            f"measurements of kind {', '.join(twice)} are given more than once",
            fix="give each kind once (one term holds all its rows, e.g. positions and distances)",
        )


def term_blocks(built: Sequence[TermBlocks]) -> tuple[list, list[ParameterBlock]]:
    """All residual blocks and all parameter blocks of ``built``, in order."""
    return [r for b in built for r in b.residuals], [p for b in built for p in b.parameters]
