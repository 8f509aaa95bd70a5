"""What every ``selfcal`` command shares: the argument error, number lists on the command line,
and the one place where an exception becomes a message and an exit code.

Exit codes (README "Exit codes"): 0 ok; 1 an internal error (a bug: ``SELFCAL_DEBUG=1`` shows
the traceback); 2 bad input; 3 the data cannot determine the calibration; 4 a robot or hardware
fault; 130 interrupted (Ctrl-C). 2, 3 and 4 are the ``exit_code`` of the
:class:`calib.errors.SelfCalError` kinds.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

import numpy as np

from calib.errors import EXIT_INTERNAL, EXIT_INTERRUPTED, InputError, SelfCalError

__all__ = ["CliError", "parse_floats", "run_command", "report_error"]


class CliError(InputError):
    """A bad command-line argument (exit code 2): printed without a traceback."""


def parse_floats(text: str, count: int | None, what: str) -> np.ndarray:
    """Comma-separated numbers such as ``"38.15,-30,45"``; ``count`` values if not None.

    Raises:
        CliError: not numbers, the wrong count or not finite (the message names ``what``).
    """
    try:
        vals = np.array([float(x) for x in text.replace(" ", "").split(",") if x != ""])
    except ValueError:
        raise CliError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if count is not None and len(vals) != count:
        raise CliError(f"{what}: expected {count} numbers, got {len(vals)} in {text!r}")
    if not np.all(np.isfinite(vals)):
        raise CliError(f"{what}: numbers must be finite, got {text!r}")
    return vals


def report_error(name: str, exc: SelfCalError) -> None:
    """Print ``NAME: error: MESSAGE``, the fix and any notes to stderr."""
    print(f"{name}: error: {exc.message}", file=sys.stderr)
    if exc.fix:
        print(f"{name}: fix: {exc.fix}", file=sys.stderr)
    for note in getattr(exc, "__notes__", []):
        print(f"  {note}", file=sys.stderr)


def run_command(
    func: Callable[[argparse.Namespace], int | None], args: argparse.Namespace, name: str
) -> int:
    """Run one command and turn its outcome into an exit code (see the module docstring).

    A :class:`SelfCalError` prints its message and fix and returns its ``exit_code`` (130 when
    it was caused by Ctrl-C); any other exception is a bug: a one-line summary and 1, or the
    traceback with ``SELFCAL_DEBUG=1``.
    """
    debug = bool(os.environ.get("SELFCAL_DEBUG"))
    try:
        return int(func(args) or 0)
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except SelfCalError as exc:
        if debug and not isinstance(exc, CliError):
            raise
        report_error(name, exc)
        return EXIT_INTERRUPTED if isinstance(exc.__cause__, KeyboardInterrupt) else exc.exit_code
    except Exception as exc:
        if debug:
            raise
        hint = "(set SELFCAL_DEBUG=1 for the traceback)"
        print(f"{name}: error: {type(exc).__name__}: {exc} {hint}", file=sys.stderr)
        return EXIT_INTERNAL
