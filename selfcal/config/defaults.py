"""Defaults every ``selfcal`` command shares, importable without numpy, scipy or OpenCV (the
parser is built from them; ``selfcal.config.scenario`` and the commands import them from here)."""

from __future__ import annotations

__all__ = ["DEFAULT_ROBOT"]

DEFAULT_ROBOT = "er4u-paper"
"""The one default robot model (and so encoder table) of every ``selfcal`` command and scenario
that names none: the [robot] model of the default scenario (``scenarios/paper.toml``), fk, ik,
render, the ``hw`` commands and ``selfcal emulate``. A real ER-4u controller's encoders read zero
at the vendor home: give ``--robot er4u-vendor`` (or ``[robot] model = "er4u-vendor"``) for it
(docs/hardware.md). The ``hw`` library's own default for callers that name no model is
``selfcal.hw.settings.DEFAULT_MODEL`` (the ACL controller's arm, er4u-vendor)."""
