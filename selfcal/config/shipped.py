"""The scenarios shipped with the package (``scenarios/*.toml``, package data of the wheel):
reachable by name from any working directory (``selfcal run mono-charuco``), listed by
``selfcal scenarios`` with the first sentence of each file's header comment."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

from selfcal.console.common import add_json
from selfcal.robot.definition import models_dir

__all__ = ["SHIPPED_DIR", "shipped_scenarios", "scenario_file", "shipped_model_file", "register"]

SHIPPED_DIR = models_dir().parent / "scenarios"
"""The folder of the shipped scenario files: ``scenarios/`` beside ``models/`` in a checkout,
``selfcal/scenarios`` beside ``selfcal/models`` in a wheel."""


def shipped_scenarios() -> dict[str, str]:
    """Name (file stem) -> one-line description of every shipped scenario, sorted by name."""
    return {p.stem: _summary(p) for p in sorted(SHIPPED_DIR.glob("*.toml"))}


def _summary(path: Path) -> str:
    """The first sentence of the file's leading comment, cut at its first colon or semicolon
    when longer than 100 characters."""
    head = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        head.append(line.lstrip("#").strip())
    text = " ".join(head)
    sentence = re.split(r"(?<=\.)\s", text, maxsplit=1)[0]
    if len(sentence) > 100:
        sentence = re.split(r"[:;]\s", sentence, maxsplit=1)[0]
    return sentence.rstrip(".")


def scenario_file(path: str | Path) -> Path | None:
    """``path`` when it is a file, else the shipped scenario it names (``mono-charuco`` or
    ``mono-charuco.toml`` without a folder), else None."""
    p = Path(path)
    if p.is_file():
        return p
    if p.parent == Path(".") and p.suffix in ("", ".toml"):
        shipped = SHIPPED_DIR / f"{p.stem}.toml"
        if shipped.is_file():
            return shipped
    return None


def shipped_model_file(scenario: Path, relative: str) -> Path | None:
    """A ``../models/...`` path of a shipped scenario found in the package's models folder (in a
    wheel the models are ``selfcal/models``, not beside ``scenarios/``), else None."""
    parts = Path(relative).parts
    if scenario.resolve().parent != SHIPPED_DIR or "models" not in parts:
        return None
    alt = models_dir().joinpath(*parts[parts.index("models") + 1 :])
    return alt if alt.is_file() else None


def cmd_scenarios(args: argparse.Namespace) -> int:
    """Print the shipped scenarios: name and description (or JSON with ``--json``)."""
    found = shipped_scenarios()
    if args.json:
        print(json.dumps({n: {"description": d, "file": str(SHIPPED_DIR / f"{n}.toml")}
                          for n, d in found.items()}))  # fmt: skip
        return 0
    width = max(map(len, found))
    for name, description in found.items():
        print(f"{name:<{width}}  {description}")
    return 0


def register(subparsers) -> None:
    """Add ``scenarios`` to the ``selfcal`` subcommands."""
    help_ = ("list the shipped scenarios (selfcal run NAME, selfcal acquire NAME, ...) with a "
             "one-line description; a copy of one is a start for your own")  # fmt: skip
    sp = subparsers.add_parser("scenarios", help=help_, description=help_)
    add_json(sp)
    sp.set_defaults(func=cmd_scenarios)
