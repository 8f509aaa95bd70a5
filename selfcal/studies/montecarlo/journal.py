"""The Monte Carlo's journal ``DIR/draws.jsonl``: what makes ``selfcal montecarlo`` resumable.

One JSON line per finished draw, ``{"key": ..., "row": {...}}``, appended and flushed the moment
the draw's row arrives (from the local pool or the cluster). An interrupted run (Ctrl-C, a lost
scheduler, a killed command) keeps every finished draw; the same command again (same settings,
same ``--out``, locally or with ``--cluster`` whichever ran the first part) computes only the
draws whose key is not in the journal, and ``--draws`` can grow to add draws. The key is the
draw's complete settings (:func:`draw_key`). JSON writes floats in their shortest exact form,
so a row read back is bit-identical to the row computed; a line cut short by a kill is ignored
(that draw runs again).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from selfcal.errors import UsageTypeError

__all__ = ["JOURNAL", "draw_key", "DrawJournal"]

JOURNAL = "draws.jsonl"
"""The journal's file name in the Monte Carlo's output folder."""


def draw_key(settings: dict) -> str:
    """The identity of a draw: its complete settings (truth, postures, noise, seed) as canonical
    JSON."""
    return json.dumps(settings, sort_keys=True, default=_plain)


def _plain(v):
    """numpy scalars and arrays as the Python numbers and lists JSON knows."""
    if isinstance(v, np.generic | np.ndarray):
        return v.tolist()
    raise UsageTypeError(f"{type(v).__name__} is not JSON serialisable")


class DrawJournal:
    """The journal file at ``path``: :meth:`load` the finished draws, :meth:`append` one more."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def load(self) -> dict[str, dict]:
        """Finished draws, key -> row (the last line of a key wins; unreadable lines, e.g. the
        last one cut short by a kill, are skipped)."""
        if not self.path.is_file():
            return {}
        out: dict[str, dict] = {}
        for line in self.path.read_text().splitlines():
            try:
                rec = json.loads(line)
                out[str(rec["key"])] = dict(rec["row"])
            except (ValueError, KeyError, TypeError):
                continue
        return out

    def append(self, key: str, row: dict) -> None:
        """Write one finished draw and flush it (to the operating system) at once."""
        data = (json.dumps({"key": key, "row": row}, default=_plain) + "\n").encode()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "ab+") as fh:
            end = fh.seek(0, 2)
            if end > 0:  # after a line cut short by a kill: start on a fresh line
                fh.seek(end - 1)
                if fh.read(1) != b"\n":
                    data = b"\n" + data
            fh.write(data)
            fh.flush()
