"""Every benchmark script's ``--help`` names the command that runs it, ``python -m
selfcal.benchmarks.PART.NAME`` (argparse named the file: ``usage: accuracy.py`` for both
``board.accuracy`` and ``tracker.accuracy``), through the one helper
:func:`selfcal.benchmarks.usage.benchmark_parser`."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import pkgutil
import re
import sys
from pathlib import Path

import pytest

import selfcal.benchmarks
from selfcal.benchmarks.usage import module_command


def _source(name: str) -> str:
    spec = importlib.util.find_spec(name)
    assert spec is not None and spec.origin is not None, name
    return Path(spec.origin).read_text()


MODULES = sorted(
    m.name for m in pkgutil.walk_packages(selfcal.benchmarks.__path__, "selfcal.benchmarks.")
)
PARSING = [
    n
    for n in MODULES
    if n != "selfcal.benchmarks.usage"
    and re.search(r"benchmark_parser\(|\barguments\(argv", _source(n))
]


def _command(name: str) -> str:
    """The module run by ``python -m``: its package, where the package's ``__main__`` runs it."""
    package = name.rsplit(".", 1)[0]
    main = f"{package}.__main__"
    runs_it = main in MODULES and f"from {name} import main" in _source(main)
    return package if runs_it else name


def test_every_parser_comes_from_the_helper():
    """No benchmark module builds its own parser (one with ``add_help=False`` is a parent of
    one built by the helper; speed.measure's fallback for a reference tree older than the helper,
    marked "an older tree's fallback", is the one other)."""
    assert len(PARSING) >= 50  # 52 modules parse arguments (session 28)
    own = [
        n
        for n in MODULES
        if n != "selfcal.benchmarks.usage"
        and re.search(
            r"ArgumentParser\((?!add_help=False).*(?<!an older tree's fallback)$", _source(n), re.M
        )
    ]
    assert own == []


@pytest.mark.parametrize("name", PARSING)
def test_help_names_the_command(name, capsys, monkeypatch):
    mod = importlib.import_module(name)
    monkeypatch.setattr(sys, "argv", [f"{name.rsplit('.', 1)[-1]}.py", "--help"])
    with pytest.raises(SystemExit) as stop:
        mod.main(["--help"]) if inspect.signature(mod.main).parameters else mod.main()
    assert stop.value.code == 0
    usage = capsys.readouterr().out.split("\n", 1)[0]
    assert re.match(rf"usage: python -m {re.escape(_command(name))}( |$)", usage), usage


def test_module_command_names_the_module_not_the_file():
    board = importlib.import_module("selfcal.benchmarks.board.accuracy")
    tracker = importlib.import_module("selfcal.benchmarks.tracker.accuracy")
    assert module_command(board.__file__) == "python -m selfcal.benchmarks.board.accuracy"
    assert module_command(tracker.__file__) == "python -m selfcal.benchmarks.tracker.accuracy"
    handeye = Path(board.__file__).parents[1] / "handeye" / "__main__.py"
    assert module_command(handeye) == "python -m selfcal.benchmarks.handeye"
    with pytest.raises(ValueError):
        module_command("/elsewhere/accuracy.py")


def test_a_copy_run_from_outside_the_package_keeps_its_file_name(tmp_path):
    """speed.measure --against runs a copy of its script from a temporary folder: the parser is
    still made, named by the copy's file (it raised ValueError: the speed block failed)."""
    from selfcal.benchmarks.usage import benchmark_parser

    ap = benchmark_parser(str(tmp_path / "speed.py"), description="x")
    assert not ap.prog.startswith("python -m")  # argparse's own: sys.argv[0]'s name
