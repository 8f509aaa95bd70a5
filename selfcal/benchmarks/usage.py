"""The benchmark scripts' argument parsers, whose usage names the command that runs them.

argparse names a script by its file (``sys.argv[0]``): ``python -m
selfcal.benchmarks.board.accuracy --help`` printed ``usage: accuracy.py``, and so did
``selfcal.benchmarks.tracker.accuracy``. :func:`benchmark_parser` names the module instead
(:func:`selfcal.console.usage.module_parser`, which the studies' and the other ``python -m``
modules' parsers use too)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from selfcal.console.usage import module_command, module_parser

__all__ = ["benchmark_parser", "module_command"]


def benchmark_parser(module_file: str | Path, **kwargs: Any) -> argparse.ArgumentParser:
    """An ``argparse.ArgumentParser`` (``kwargs`` as its own: ``description``, ``parents``
    ...) whose usage and errors name the command of the module ``module_file`` (the caller's
    ``__file__``, :func:`selfcal.console.usage.module_command`), not its file name; a module
    that its package's ``__main__.py`` runs passes that file (``python -m
    selfcal.benchmarks.tracker``). A copy of a module run from outside the package
    (``speed.measure --against`` runs its script so) keeps argparse's own name, its file's."""
    return module_parser(module_file, **kwargs)
