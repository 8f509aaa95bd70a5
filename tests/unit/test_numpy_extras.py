"""numpy's subpackages that scipy's import loads unused are deferred by the command line
(selfcal.console.numpy_extras, issue 32): not loaded by scipy, loaded whole at their first use.
Checked in a fresh interpreter by sys.modules, not by timing."""

from __future__ import annotations

import json
import subprocess
import sys

# a module each deferred subpackage's load imports
INSIDE = ("numpy.f2py.f2py2e", "numpy.testing._private.utils")


def _run(code: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_scipy_loads_none_of_them_and_each_loads_at_its_first_use():
    got = _run(
        "import json, sys\n"
        "from selfcal.console.numpy_extras import defer_numpy_extras\n"
        "first = defer_numpy_extras()\n"
        "import scipy.sparse, numpy as np\n"
        f"after_scipy = [m for m in {INSIDE!r} if m in sys.modules]\n"
        "np.testing.assert_allclose(np.ones(2), 1.0)\n"
        "include = np.f2py.get_include()\n"
        f"after_use = [m for m in {INSIDE!r} if m in sys.modules]\n"
        "print(json.dumps(dict(first=first, second=defer_numpy_extras(), "
        "after_scipy=after_scipy, after_use=after_use, include=include)))"
    )
    assert got["first"] == ["numpy.f2py", "numpy.testing"]
    assert got["second"] == []  # each already bound: nothing to do
    assert got["after_scipy"] == []
    assert got["after_use"] == list(INSIDE)
    assert got["include"].endswith("src")  # numpy.f2py's own function ran


def test_the_command_line_defers_them_before_a_command_runs():
    got = _run(
        "import contextlib, io, json, sys\nimport selfcal.cli.main as c\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    code = c.main(['fk', '--joints', '0,0,0,0,0'])\n"
        "print(json.dumps(dict(code=code, lazy=type(sys.modules['numpy.f2py']).__name__)))"
    )
    assert got == {"code": 0, "lazy": "_LazyModule"}
