"""The one door to matplotlib for the studies' plots (files only, never a window)."""

from __future__ import annotations

from types import ModuleType

__all__ = ["pyplot"]


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the non-interactive Agg backend.

    Imported here, on first use, not at the top of the studies: it takes ~1 s
    (``python -X importtime``) and only the commands that draw need it.
    """
    import matplotlib  # optional and slow: see the docstring

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional and slow: see the docstring

    return plt
