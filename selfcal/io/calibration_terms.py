"""``calibration.json``'s measurement sections: one object per term the calibration estimated.

A calibration that estimated more than the dataset's images (tracker measurements, touch-probe
points ...: the terms of :mod:`selfcal.terms`) lists its ``sources`` -- ``"images"`` and then each
term's kind, in order -- and writes each term's section under its kind. This module reads them:
a kind whose section type the caller passes (:func:`selfcal.terms.registry.read_calibration`
passes every registered one) is read and checked as that type; any other is kept as it was written
(:class:`RawSection`), so a file written by a newer version with a kind this one does not know is
still read and written back unchanged. Files without ``sources`` have no sections.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from selfcal.io.jsonfile import Fields

__all__ = ["Section", "SectionType", "RawSection", "read_sections", "IMAGES"]

IMAGES = "images"
"""The first of ``sources``: the dataset's images (the route's own measurements)."""


class Section(Protocol):
    """A term's ``calibration.json`` section, written under the key ``kind``."""

    @property
    def kind(self) -> str:
        """The key of the section (the term's kind)."""

    def to_json(self) -> dict:
        """The section's JSON object."""

    def summary(self) -> str:
        """One line for people on what the section records."""


class SectionType(Protocol):
    """A section's type: reads one from its JSON object."""

    def from_json(self, f: Fields) -> Section:
        """The section in ``f`` (raises the kind ``f`` raises for a missing or malformed key)."""


@dataclass(frozen=True, eq=False)
class RawSection:
    """A section of a kind the reader was not given: its JSON object as written."""

    kind: str
    doc: dict

    def to_json(self) -> dict:
        """The object as it was read."""
        return self.doc

    def summary(self) -> str:
        """One line saying what it is."""
        return f"{self.kind}: a measurement section ({len(self.doc)} keys) read as written"


def read_sections(f: Fields, types: Mapping[str, SectionType]) -> tuple[Section, ...]:
    """The sections that ``f``'s ``sources`` name (after ``"images"``), in order.

    Raises:
        InputError (the kind ``f`` raises): ``sources`` that does not start with ``"images"``,
            names a kind twice, or a section that is missing or malformed (named).
    """
    if not f.has("sources"):
        return ()
    sources = f.strs("sources")
    if not sources or sources[0] != IMAGES or len(set(sources)) != len(sources):
        raise f.bad("sources", f"'{IMAGES}' and then each measurement kind once", list(sources))
    out: list[Section] = []
    for kind in sources[1:]:
        sub = f.sub(kind)
        t = types.get(kind)
        out.append(RawSection(kind, dict(sub.doc)) if t is None else t.from_json(sub))
    return tuple(out)
