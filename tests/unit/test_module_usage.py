"""Every ``python -m selfcal...`` module outside the benchmarks (tests/unit/test_benchmark_usage.py
checks those) names that command in its ``--help``: ``python -m
selfcal.studies.montecarlo.render --help`` printed ``usage: render.py`` and
``selfcal.studies.diagnose_render`` ``usage: diagnose_render.py`` (argparse names the file)."""

from __future__ import annotations

import contextlib
import io
import pkgutil
import runpy
import sys
from importlib.util import find_spec
from pathlib import Path

import pytest

import selfcal

MAIN = 'if __name__ == "__main__"'
MODULES = sorted(
    m.name
    for m in pkgutil.walk_packages(selfcal.__path__, "selfcal.")
    if not m.name.startswith("selfcal.benchmarks.")
    and m.name != "selfcal.cli.main"  # the `selfcal` command itself: its usage says `selfcal`
    and MAIN in Path(find_spec(m.name).origin).read_text()
)


def test_the_modules_run_with_python_m_are_found():
    assert {"selfcal.studies.montecarlo.render", "selfcal.studies.diagnose_render",
            "selfcal.cli.docs", "selfcal.sim.build_models"} <= set(MODULES)  # fmt: skip


@pytest.mark.parametrize("name", MODULES)
@pytest.mark.filterwarnings("ignore:.*found in sys.modules:RuntimeWarning")  # imported before
def test_help_names_the_command(name, monkeypatch):
    """As ``python -m NAME --help`` runs it: ``sys.argv[0]`` the module's file."""
    monkeypatch.setattr(sys, "argv", [find_spec(name).origin, "--help"])
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as done:
        runpy.run_module(name, run_name="__main__", alter_sys=False)
    assert done.value.code == 0
    assert out.getvalue().startswith(f"usage: python -m {name} "), out.getvalue()[:200]
