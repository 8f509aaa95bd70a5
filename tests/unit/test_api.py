"""The public API (selfcal/__init__.py, docs/api.md): its names resolve lazily, ``import selfcal``
stays cheap, the names mypy sees are the names it serves, and the computing functions run with
the thread limit (selfcal/threads.py)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import selfcal
import selfcal.calibration.routes as routes
from selfcal.threads import THREADS_ENV

INIT = Path(selfcal.__file__)


def test_import_selfcal_loads_no_numerics():
    code = (
        "import sys, selfcal; "
        "print(sorted(m for m in ('numpy', 'scipy', 'cv2', 'typing', 'selfcal.calibration') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_every_public_name_resolves_and_is_listed():
    assert sorted(selfcal.__all__) == selfcal.__all__  # one place to read them
    assert set(selfcal.__all__) == set(selfcal._WHERE)
    for name in selfcal.__all__:
        assert getattr(selfcal, name) is getattr(sys.modules[selfcal._WHERE[name]], name)
    assert set(selfcal.__all__) <= set(dir(selfcal))
    with pytest.raises(AttributeError, match="no attribute 'calibrat'"):
        selfcal.calibrat  # noqa: B018


def test_the_type_checker_sees_the_names_served():
    """The ``if TYPE_CHECKING:`` imports (what mypy checks callers against) are the names
    ``__getattr__`` serves, each from the same module."""
    tree = ast.parse(INIT.read_text())
    seen = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name):
            if node.test.id != "TYPE_CHECKING":
                continue
            for imp in node.body:
                if isinstance(imp, ast.ImportFrom):
                    for alias in imp.names:
                        assert alias.asname == alias.name  # an explicit re-export
                        seen[alias.name] = imp.module
    assert seen == selfcal._WHERE


def _blas_threads() -> set[int]:
    return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}


@pytest.mark.parametrize(("name", "inner"), [("calibrate", "dataset_route"),
                                             ("evaluate", "calibration_route")])  # fmt: skip
@pytest.mark.parametrize("env", [None, "2"])
def test_the_computing_functions_run_with_the_thread_limit(monkeypatch, name, inner, env):
    """Inside ``selfcal.calibrate`` / ``evaluate`` the BLAS pools hold ``SELFCAL_THREADS`` (else 1)
    threads, whatever the caller set; the caller's limit is back afterwards."""
    if env is None:
        monkeypatch.delenv(THREADS_ENV, raising=False)
    else:
        monkeypatch.setenv(THREADS_ENV, env)
    seen = []

    class Stop(Exception):
        pass

    def record(*_a, **_k):
        seen.append(_blas_threads())
        raise Stop

    monkeypatch.setattr(routes, inner, record)
    with threadpool_limits(limits=3):
        outer = _blas_threads()
        with pytest.raises(Stop):
            getattr(selfcal, name)("no-such-dataset", *(["held"] if name == "evaluate" else []))
        assert _blas_threads() == outer == {3}
    assert seen == [{1 if env is None else 2}]
