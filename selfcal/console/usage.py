"""The argument parsers of modules run with ``python -m``, whose usage names that command.

argparse names a program by its file (``sys.argv[0]``): ``python -m
selfcal.studies.montecarlo.render --help`` printed ``usage: render.py``, ``python -m
selfcal.benchmarks.board.accuracy`` ``usage: accuracy.py``. :func:`module_parser` names the
module instead (the benchmarks' :func:`selfcal.benchmarks.usage.benchmark_parser` is it)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

__all__ = ["module_command", "module_parser"]

_PACKAGE_ROOT = Path(__file__).resolve().parents[2]  # the folder that holds selfcal/


def module_command(module_file: str | Path) -> str:
    """``python -m selfcal.PART.NAME`` for the module whose ``__file__`` is ``module_file`` (a
    package's ``__init__.py`` or ``__main__.py``: the package's name). Raises ``ValueError``
    for a file outside the package."""
    path = Path(module_file).resolve().with_suffix("")
    parts = list(path.relative_to(_PACKAGE_ROOT).parts)
    if parts[-1] in ("__init__", "__main__"):
        parts.pop()
    return "python -m " + ".".join(parts)


def module_parser(module_file: str | Path, **kwargs: Any) -> argparse.ArgumentParser:
    """An ``argparse.ArgumentParser`` (``kwargs`` as its own: ``description``, ``parents``
    ...) whose usage and errors name the command of the module ``module_file`` (the caller's
    ``__file__``, :func:`module_command`), not its file name; a module that its package's
    ``__main__.py`` runs passes that file. A copy of a module run from outside the package
    keeps argparse's own name, its file's."""
    try:
        prog: str | None = module_command(module_file)
    except ValueError:
        prog = None
    return argparse.ArgumentParser(prog=prog, **kwargs)
