"""numpy's rarely used subpackages loaded when a command first uses them, not when scipy loads.

Every scipy subpackage imports ``scipy._lib._util``, which imports its vendored
``array_api_compat.numpy``; that clones numpy's namespace (``from numpy import *`` and a
``hasattr`` of every name in ``dir(numpy)``), and numpy loads its subpackages on first attribute
access (PEP 562), so the clone imports ``numpy.f2py`` (with ``charset_normalizer``),
``numpy.testing``, ``numpy.ma`` and ``numpy.polynomial``. ``numpy.ma`` (``numpy.unique``
loads it) and ``numpy.polynomial`` (``scipy.stats`` imports it at its own import: ``selfcal
check`` and ``identify`` load it) stay as they are; ``numpy.f2py`` and ``numpy.testing``, which no command uses, cost more CPU than the
rest of ``import scipy.sparse`` (issue 32):
``uv run python -X importtime -c "import scipy.sparse"``.

:func:`defer_numpy_extras` binds each of them, not yet imported, as an
:class:`importlib.util.LazyLoader` module: the clone copies the name without loading it, and the
first attribute access loads the real module in place (the same module object, the same
contents). Only the command line calls it (:mod:`selfcal.cli.main`), before a command runs; the
library leaves numpy as it is.
"""

from __future__ import annotations

import importlib.util
import sys

__all__ = ["DEFERRED", "defer_numpy_extras"]

# numpy's subpackages that scipy's namespace clone loads and no command uses. Not deferred: a
# module a command may load on a worker thread, because before Python 3.12 a lazy module's
# load is not safe against a second thread using it meanwhile (four threads' first
# np.polynomial.Polynomial raised AttributeError): numpy.ma (numpy.unique loads it) and
# numpy.polynomial (scipy.stats imports it).
DEFERRED = ("numpy.f2py", "numpy.testing")


def defer_numpy_extras() -> list[str]:
    """Bind :data:`DEFERRED`'s modules not yet imported as lazily loaded modules on ``numpy``
    (see the module's text); returns their names. A module already imported is left alone, so
    a second call does nothing."""
    import numpy  # noqa: F401 - the parent package must exist before its submodules

    deferred = []
    for name in DEFERRED:
        if name in sys.modules:
            continue
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:  # pragma: no cover - numpy always has them
            continue
        loader = importlib.util.LazyLoader(spec.loader)
        spec.loader = loader
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        loader.exec_module(module)  # records the load; runs it at the first attribute access
        parent, _, child = name.rpartition(".")
        setattr(sys.modules[parent], child, module)
        deferred.append(name)
    return deferred
