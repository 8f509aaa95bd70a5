"""What every ``selfcal`` command shares: the argument error, number lists on the command line,
and the one place where an exception becomes a message and an exit code.

Every failure is one line on stderr, ``selfcal: error: <what> (<file/key/row>) -- <fix>``, and
no traceback unless ``-v``. Exit codes (README "Exit codes", docs/cli.md): 0 ok; 1 an internal
error (a bug: ``-v`` prints the traceback, ``SELFCAL_DEBUG=1`` re-raises it); 2 bad input or a
bad command line; 3 the data cannot determine the calibration; 4 a robot or hardware fault; 130
interrupted (Ctrl-C); 141 the reader of stdout went away (a closed pipe: nothing reported). 2, 3 and 4 are the ``exit_code`` of the :class:`selfcal.errors.SelfCalError`
kinds.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import select
import shlex
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import NoReturn

import numpy as np

from selfcal.console.log import command_logging, get_logger, wrote_line
from selfcal.errors import (
    EXIT_BROKEN_PIPE,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    InputError,
    SelfCalError,
)

__all__ = [
    "writing",
    "CliError",
    "SelfcalParser",
    "parse_floats",
    "run_command",
    "report_error",
    "error_line",
    "note_written",
    "add_verbosity",
    "add_deprecated",
    "add_json",
    "add_scenario_arg",
    "leaf_parsers",
    "EXIT_USAGE",
]

EXIT_USAGE = 2
"""A bad command line (argparse) is bad input too."""


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


def error_line(exc: SelfCalError) -> str:
    """``selfcal: error: <message> -- <fix>``: the message names the file, key or row at fault
    (:mod:`selfcal.errors`), the fix what to do about it."""
    fix = f" -- {exc.fix}" if exc.fix else ""
    return f"selfcal: error: {exc.message}{fix}"


def report_error(exc: SelfCalError) -> None:
    """Print :func:`error_line` and any notes (indented) to stderr."""
    print(error_line(exc), file=sys.stderr)
    for note in getattr(exc, "__notes__", []):
        print(f"  {note}", file=sys.stderr)


class SelfcalParser(argparse.ArgumentParser):
    """An argument parser whose usage errors read like every other error: the usage, then
    ``selfcal: error: <problem> -- see `selfcal CMD --help``` and exit code 2.

    A value that starts with a minus and a digit is a value, not an option: argparse alone
    takes ``-10`` for a number but ``-10,20,30`` for an unknown option, so ``--joints
    -10,20,30,0,0`` failed with "expected one argument" (no ``selfcal`` option is spelled like
    a number)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d[\d.,eE+\- ]*$")

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"selfcal: error: {message} -- see `{self.prog} --help`\n")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but arguments no option takes are reported by the command they were
        given to (its usage and ``--help``), and an option that belongs to other commands names
        them (``selfcal calibrate DIR --spread 10``: ``--spread`` is ``selfcal identify``'s)."""
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            command = _chosen_parser(self, ns)
            elsewhere = _commands_with_options(self, extra, command)
            command.error(f"unrecognized arguments: {' '.join(extra)}{elsewhere}")
        return ns


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The sub-command parsers of ``parser`` by name (none for a leaf command)."""
    return {
        name: sub
        for action in parser._actions
        if isinstance(action, argparse._SubParsersAction)
        for name, sub in action.choices.items()
    }


def _chosen_parser(
    parser: argparse.ArgumentParser, ns: argparse.Namespace
) -> argparse.ArgumentParser:
    """The parser of the (nested) command chosen in ``ns`` (``parser`` itself if none)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            chosen = action.choices.get(getattr(ns, action.dest, None) or "")
            if chosen is not None:
                return _chosen_parser(chosen, ns)
    return parser


def _commands_with_options(
    top: argparse.ArgumentParser, extra: list[str], command: argparse.ArgumentParser
) -> str:
    """``` (`--spread` is an option of `selfcal identify`)``` for every option in ``extra``
    that other commands of ``top`` have, else an empty string."""
    leaves: list[argparse.ArgumentParser] = []
    todo = [top]
    while todo:
        p = todo.pop()
        subs = _subcommands(p)
        todo += list(subs.values())
        if not subs and p is not command:
            leaves.append(p)
    notes = []
    for token in dict.fromkeys(t.split("=", 1)[0] for t in extra if t.startswith("--")):
        progs = sorted({p.prog for p in leaves if token in p._option_string_actions})
        if progs:
            notes.append(f"`{token}` is an option of " + ", ".join(f"`{q}`" for q in progs))
    return f" ({'; '.join(notes)})" if notes else ""


def add_verbosity(p: argparse.ArgumentParser, *, top: bool = False) -> None:
    """``-v/--verbose`` (tracebacks, debug messages) and ``-q/--quiet`` (no progress, no notes;
    warnings, errors and the last line stay). Accepted before the command (``top``) and after
    it; a sub-command's default does not overwrite a flag given before it."""
    default = False if top else argparse.SUPPRESS
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=default,
        help="tracebacks and debug messages" if top else argparse.SUPPRESS,
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=default,
        help="no progress bars or notes (warnings, errors and the last line stay)"
        if top
        else argparse.SUPPRESS,
    )


def leaf_parsers(p: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """The parsers of every command (those without sub-commands of their own), depth first."""
    subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [p]
    out: list[argparse.ArgumentParser] = []
    for action in subs:
        for child in dict.fromkeys(action.choices.values()):  # an alias maps to the same parser
            out.extend(leaf_parsers(child))
    return out


class _DeprecatedOption(argparse.Action):
    """A hidden old spelling of an option: stores into the new option's ``dest`` and leaves a
    note that :func:`run_command` logs as a warning."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs) -> None:
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, values)
        notes = list(getattr(namespace, "deprecated", None) or [])
        notes.append(f"{option_string} is deprecated and will be removed: use {self.new}")
        namespace.deprecated = notes


def add_deprecated(p: argparse.ArgumentParser, old: str, new: str, dest: str, **kwargs) -> None:
    """Accept ``old`` (hidden from ``--help``) as a deprecated spelling of option ``new`` (whose
    value lands in ``dest``); using it logs ``selfcal: warning: OLD is deprecated ... use NEW``."""
    p.add_argument(
        old, dest=dest, action=_DeprecatedOption, new=new, help=argparse.SUPPRESS,
        default=argparse.SUPPRESS, **kwargs,
    )  # fmt: skip


def add_json(p: argparse.ArgumentParser, *, always: bool = False) -> None:
    """``--json``: the command's result as one JSON object on stdout (its notes go to stderr).
    ``always``: the command prints JSON anyway (the flag is accepted for one grammar)."""
    p.add_argument(
        "--json",
        action="store_true",
        help="the result as JSON on stdout (this command always prints JSON)"
        if always
        else "the result as one JSON object on stdout (notes and progress on stderr)",
    )


def add_scenario_arg(p: argparse.ArgumentParser, what: str) -> None:
    """The optional positional ``SCENARIO`` (``args.scenario``, None: the default scenario),
    with ``--config`` as its deprecated spelling."""
    p.set_defaults(scenario=None)  # first: set_defaults also resets the defaults of actions
    p.add_argument(
        "scenario",
        nargs="?",
        metavar="SCENARIO",
        default=argparse.SUPPRESS,  # keeps a value given by the old --config
        help=f"scenario TOML {what}, or a shipped scenario's name (`selfcal scenarios`; default "
        "paper)",
    )
    add_deprecated(p, "--config", "the positional SCENARIO", dest="scenario")


def _debug(args: argparse.Namespace) -> tuple[bool, bool]:
    """(re-raise, print traceback): ``SELFCAL_DEBUG=1`` re-raises (for a debugger), ``-v``
    prints the traceback before the error line."""
    return bool(os.environ.get("SELFCAL_DEBUG")), bool(getattr(args, "verbose", False))


def run_command(func: Callable[[argparse.Namespace], int | None], args: argparse.Namespace) -> int:
    """Run one command and turn its outcome into an exit code (see the module docstring).

    Warnings go through :mod:`selfcal.console.log` (one format, counted); the command records what
    it wrote in ``args.log`` (:class:`selfcal.console.log.CommandLog`) and the last line names it.
    A :class:`SelfCalError` prints :func:`error_line` and returns its ``exit_code`` (130 when
    it was caused by Ctrl-C); one whose ``exit_code`` is 1 (``UsageError``, ``InternalError``)
    and any other exception is a bug: one line and 1 (``-v``: with the traceback;
    ``SELFCAL_DEBUG=1``: re-raised).
    """
    reraise, trace = _debug(args)
    t0 = time.perf_counter()
    with command_logging(verbose=trace, quiet=bool(getattr(args, "quiet", False))) as log:
        args.log = log
        for note in getattr(args, "deprecated", None) or []:
            get_logger("cli").warning("%s", note)
        try:
            code = int(func(args) or 0)
            sys.stdout.flush()  # a closed pipe shows here, not at the interpreter's exit
        except BrokenPipeError as exc:
            if _stdout_gone():
                return _reader_gone()
            if reraise:  # a pipe or socket of the command's own: a bug, not a reader gone
                raise
            return _internal(exc, trace)
        except KeyboardInterrupt:
            print("selfcal: error: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        except SelfCalError as exc:
            if reraise and not isinstance(exc, CliError):
                raise
            if exc.exit_code == EXIT_INTERNAL:  # a bug (UsageError, InternalError)
                return _internal(exc, trace)
            if trace:
                traceback.print_exc()
            report_error(exc)
            return (
                EXIT_INTERRUPTED if isinstance(exc.__cause__, KeyboardInterrupt) else exc.exit_code
            )
        except Exception as exc:
            if reraise:
                raise
            return _internal(exc, trace)
        line = wrote_line(log, time.perf_counter() - t0)
        if line:
            print(line, file=sys.stderr, flush=True)
        return code


def _stdout_gone() -> bool:
    """Whether stdout is a pipe whose reader has closed it (poll reports an error on its write
    end), so a BrokenPipeError came from our output and not from a pipe of the command's own;
    False where stdout has no file descriptor (captured)."""
    try:
        fd = sys.stdout.fileno()
    except (OSError, ValueError, AttributeError):
        return False
    try:
        poll = select.poll()
    except AttributeError:  # no poll() on this platform: take the error for stdout's
        return True
    poll.register(fd, select.POLLOUT)
    return any(event & select.POLLERR for _, event in poll.poll(0))


def _reader_gone() -> int:
    """The reader of stdout closed it (``selfcal scenarios | head -1``): stop quietly, as a Unix
    tool killed by SIGPIPE does, with stdout pointed at /dev/null so that the interpreter's
    last flush does not raise again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # no file descriptor behind sys.stdout (captured): nothing to do
        pass
    return EXIT_BROKEN_PIPE


def _internal(exc: Exception, trace: bool) -> int:
    """Report ``exc`` as an internal error (a bug): one line, the traceback with ``-v``."""
    if trace:
        traceback.print_exc()
    hint = "" if trace else "; run again with -v for the traceback"
    print(
        f"selfcal: error: internal error {type(exc).__name__}: {exc} -- a bug{hint}",
        file=sys.stderr,
    )
    return EXIT_INTERNAL


def note_written(args: argparse.Namespace, *paths: str | Path) -> None:
    """Record files or folders a command wrote (its last line names them); a no-op for a
    namespace not run through :func:`run_command`."""
    log = getattr(args, "log", None)
    if log is not None:
        log.add_written(*paths)


@contextlib.contextmanager
def writing(
    args: argparse.Namespace, folder: str | Path, what: str = "--out", *, create: bool = True
) -> Iterator[None]:
    """Hold the lock of the output ``folder`` while a command writes it
    (:func:`selfcal.io.outlock.output_lock`: one writer per folder; a second stops with exit code 2
    naming the first; a stale lock is taken over with a warning). ``create``: make a missing
    folder (False: a missing folder is the command's own error to report, nothing is locked)."""
    from selfcal.io.outlock import output_lock

    if not create and not Path(folder).is_dir():
        yield
        return
    command = "selfcal " + shlex.join(getattr(args, "argv", None) or sys.argv[1:])
    with output_lock(folder, command, what) as note:
        if note:
            get_logger("cli").warning("%s", note)
        yield
