"""The messages of one ``selfcal`` command: warnings and notes through :mod:`logging` in one
format, a count of the warnings, and what the command wrote (its last line).

Every line the command line prints about the run (not its results) has the form
``selfcal: <level>: <text>`` on stderr: ``selfcal: warning: ...`` for a warning raised anywhere
(Python ``warnings`` are routed here too, without their source path), ``selfcal: error: ...`` for
the failure (:func:`selfcal.console.common.run_command`). The last line names what was written and
counts the warnings: ``selfcal: wrote runs/paper (calibration.json, report.md); 1 warning``.

Library code logs through ``logging.getLogger("selfcal.<module>")`` (:func:`get_logger`); the
command line installs the one handler for the time of a command (:func:`command_logging`) and
removes it afterwards, so nothing global outlives a call of :func:`selfcal.cli.main.main`.
"""

from __future__ import annotations

import logging
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from selfcal.errors import SelfCalWarning

__all__ = ["LOGGER", "get_logger", "CommandLog", "command_logging", "wrote_line"]

LOGGER = "selfcal"
"""Name of the root logger of the project's messages."""


def get_logger(name: str) -> logging.Logger:
    """The logger ``selfcal.<name>`` (e.g. ``get_logger(__name__)``)."""
    return logging.getLogger(name if name.startswith(LOGGER + ".") else f"{LOGGER}.{name}")


@dataclass
class CommandLog:
    """What one command reported: ``warnings`` (count) and the paths it ``wrote``."""

    warnings: int = 0
    wrote: list[Path] = field(default_factory=list)

    def add_written(self, *paths: str | Path) -> None:
        """Record output files or folders (in the order written; repeats are kept once)."""
        for p in paths:
            if Path(p) not in self.wrote:
                self.wrote.append(Path(p))


class _Handler(logging.Handler):
    """``selfcal: <level>: <message>`` on the current ``sys.stderr`` (looked up per record, so
    a redirected stderr is honoured); counts warnings and worse into ``log``."""

    def __init__(self, log: CommandLog, level: int) -> None:
        super().__init__(level)
        self.log = log
        self.seen: set[tuple[int, str]] = set()

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
        except Exception:  # a malformed message must not end the command
            text = str(record.msg)
        if record.levelno >= logging.WARNING:
            # a result's warnings are also raised as Python warnings where they arise: once
            key = (record.levelno, text.split(" [")[0])
            if key in self.seen:
                return
            self.seen.add(key)
            self.log.warnings += 1
        level = record.levelname.lower()
        prefix = "selfcal: " if level == "info" else f"selfcal: {level}: "
        # on a terminal, a progress bar may be drawn on the current line: erase it first
        clear = "\r\033[K" if getattr(sys.stderr, "isatty", lambda: False)() else ""
        print(clear + prefix + text, file=sys.stderr, flush=True)


def _is_printer(impl) -> bool:
    """Whether ``impl`` is the warnings module's own printing ``_showwarnmsg_impl`` (and not the
    recorder of an enclosing ``warnings.catch_warnings(record=True)``)."""
    return getattr(impl, "__module__", None) == "warnings" and (
        getattr(impl, "__name__", None) == "_showwarnmsg_impl"
    )


def _warning_router(recorder):
    """A ``warnings.showwarning`` replacement: the warning as a ``selfcal: warning:`` log line
    (no source path, no code line; the category only when it is not one of the project's), also
    handed to ``recorder`` (an enclosing ``catch_warnings(record=True)``) when there is one."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        plain = issubclass(category, SelfCalWarning) or category is UserWarning
        tag = "" if plain else f" [{category.__name__}]"
        get_logger("warnings").warning("%s%s", str(message), tag)
        if recorder is not None:
            recorder(warnings.WarningMessage(message, category, filename, lineno, file, line))

    return show


@contextmanager
def command_logging(*, verbose: bool = False, quiet: bool = False) -> Iterator[CommandLog]:
    """Install the ``selfcal`` log handler and route Python warnings to it for one command.

    A warning repeated word for word (the same text raised as a Python warning and listed in a
    result) is printed and counted once. ``verbose``: debug messages too; ``quiet``: warnings and errors only (no info notes).
    Yields the :class:`CommandLog` that counts the warnings.
    """
    log = CommandLog()
    level = logging.DEBUG if verbose else logging.WARNING if quiet else logging.INFO
    root = logging.getLogger(LOGGER)
    handler = _Handler(log, level)
    old_level, old_propagate = root.level, root.propagate
    root.addHandler(handler)
    root.setLevel(level)
    root.propagate = False
    try:
        outer = getattr(warnings, "_showwarnmsg_impl", None)
        recorder = None if outer is None or _is_printer(outer) else outer
        with warnings.catch_warnings():
            warnings.showwarning = _warning_router(recorder)
            yield log
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)
        root.propagate = old_propagate


def wrote_line(log: CommandLog, seconds: float) -> str | None:
    """The last line of a command: what it wrote, how long it took and the warning count; None
    when it wrote nothing and warned nothing (a command that only prints its result)."""
    n = log.warnings
    counted = f"{n} warning{'s' if n != 1 else ''}"
    if not log.wrote:
        return None if n == 0 else f"selfcal: done in {seconds:.1f} s, nothing written; {counted}"
    parts = []
    for p in log.wrote:
        if p.is_dir():
            names = sorted(c.name for c in p.iterdir() if c.is_file())
            shown = ", ".join(names[:6]) + (f", ... ({len(names)} files)" if len(names) > 6 else "")
            parts.append(f"{p}/ ({shown})" if names else f"{p}/")
        else:
            parts.append(str(p))
    return f"selfcal: wrote {'; '.join(parts)} in {seconds:.1f} s; {counted}"
