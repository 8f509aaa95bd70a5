"""The one door to matplotlib for the studies' plots (files only, never a window)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import Any

from calib.io.atomic import write_with_atomic

__all__ = ["pyplot", "save_figure"]


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` on the non-interactive Agg backend.

    Imported here, on first use, not at the top of the studies: it takes ~1 s
    (``python -X importtime``) and only the commands that draw need it.
    """
    import matplotlib  # optional and slow: see the docstring

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional and slow: see the docstring

    return plt


def save_figure(fig: Any, path: str | Path, **kwargs: Any) -> Path:
    """``fig.savefig`` to ``path`` atomically (:mod:`calib.io.atomic`), in the format of its
    extension."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    return write_with_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, **kwargs))
