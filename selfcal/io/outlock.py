"""One writer per output folder: a lock file naming the process that writes the folder.

Two ``selfcal run --out same`` at once used to interleave their rows (``joints.csv`` with frames
0-15 twice) and end in an unusable dataset. A command that writes a folder holds
``FOLDER/.selfcal.lock`` while it runs: a small JSON object with the writer's ``pid``, ``host``,
``command`` and ``started`` (local time, ISO 8601), written beside it and hard-linked into place
(``link`` fails when the name exists), so that of two processes exactly one gets it and no reader
sees it half written. A second writer finds it and stops with
:class:`OutputBusyError` (exit code 2) before it touches anything else in the folder. A lock whose
process is no longer running on this host (killed, a power cut) is stale: it is taken over, and
the caller gets a note saying whose it was. The lock also records the process's start (Linux:
``/proc/PID/stat``'s start time since boot, in clock ticks), so a pid that a new process took after a
crash does not keep the lock held. A lock from another host cannot be checked and is held.

:func:`prepare_folder` also refuses an output path that cannot be a folder: an existing file, a
path below a file, a place where folders cannot be made (``/proc``), each as an
:class:`selfcal.errors.InputError` naming the path.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

from selfcal.errors import InputError
from selfcal.io.atomic import write_text_atomic

__all__ = [
    "LOCK_NAME",
    "OutputBusyError",
    "new_folder",
    "prepare_folder",
    "remove_output",
    "removed_on_failure",
    "output_lock",
]

LOCK_NAME = ".selfcal.lock"


class OutputBusyError(InputError):
    """Another process writes the output folder (exit code 2); the message names it."""


def prepare_folder(folder: str | Path, what: str = "--out") -> Path:
    """``folder``, created with its parents when missing.

    Raises:
        InputError: ``folder`` is an existing file, lies below a file, or cannot be created
            (the path and the reason named; ``what`` names the option or argument).
    """
    folder = Path(folder)
    fix = "give a folder that can be created (a path where you may write, not an existing file)"
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{what} {folder}: exists and is not a folder", fix=fix)
    parent = next((p for p in folder.parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise InputError(f"{what} {folder}: {parent} is a file, not a folder", fix=fix)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"{what} {folder}: cannot create the folder ({exc.strerror or exc})", fix=fix
        ) from None
    return folder


def new_folder(folder: str | Path) -> bool:
    """Whether ``folder`` is missing or holds nothing but this command's output lock (a folder the
    command may empty again when it fails, see :func:`remove_output`)."""
    folder = Path(folder)
    if not folder.exists():
        return True
    names = {p.name for p in folder.iterdir()} if folder.is_dir() else {""}
    return bool(names) and all(n.startswith(LOCK_NAME) for n in names)


def remove_output(folder: str | Path) -> None:
    """Remove what a failed command wrote into the :func:`new_folder` ``folder``: everything but
    its output lock, or the folder itself when it holds no lock (the lock's holder removes the
    folder it made when it releases the lock, :func:`output_lock`)."""
    folder = Path(folder)
    if not (folder / LOCK_NAME).exists():
        shutil.rmtree(folder, ignore_errors=True)
        return
    for p in folder.iterdir():
        if p.name.startswith(LOCK_NAME):
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                p.unlink()


@contextmanager
def removed_on_failure(folder: str | Path) -> Iterator[None]:
    """Remove ``folder`` when the block fails and ``folder`` did not exist before it (or held only
    the output lock of the command that runs the block: :func:`new_folder`, :func:`remove_output`);
    the exception goes on."""
    created = new_folder(folder)
    try:
        yield
    except BaseException:
        if created:
            remove_output(folder)
        raise


def _start_ticks(pid: int) -> int | None:
    """The start of process ``pid`` (clock ticks after boot, ``/proc/PID/stat`` field 22), or None
    where there is no /proc (not Linux) or no such process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    try:  # the command name (field 2) is in parentheses and may hold spaces
        return int(stat[stat.rindex(")") + 2 :].split()[19])
    except (ValueError, IndexError):
        return None


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` runs on this host (one we may not signal runs too)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OverflowError:
        return False
    return True


def _read(path: Path) -> dict:
    """The lock's content, or ``{}`` for a damaged one (or one removed this instant)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return doc if isinstance(doc, dict) else {}


def _describe(doc: dict) -> str:
    return (
        f"pid {doc.get('pid', '?')} on {doc.get('host', '?')}, `{doc.get('command', '?')}`, "
        f"started {doc.get('started', '?')}"
    )


def _stale(doc: dict) -> bool:
    pid = doc.get("pid")
    if (
        doc.get("host") != socket.gethostname()
        or not isinstance(pid, int)
        or isinstance(pid, bool)
        or pid == os.getpid()
    ):
        return False
    if not _alive(pid):
        return True
    started = doc.get("start_ticks")  # a living pid another process took after a crash
    now = _start_ticks(pid)
    return isinstance(started, int) and now is not None and now != started


def _take(path: Path, staged: Path, what: str) -> str | None:
    """Link the written lock ``staged`` to ``path`` (exclusive, and never seen half written);
    returns the note of a stale lock taken over."""
    folder, note = path.parent, None
    for _ in range(3):
        try:
            os.link(staged, path)
        except FileExistsError:
            other = _read(path)
            if not _stale(other):
                raise OutputBusyError(
                    f"{what} {folder}: another selfcal writes this folder ({_describe(other)}); "
                    f"nothing was written",
                    fix=f"wait for it to finish, or give another {what}; if no selfcal runs, "
                    f"remove {path}",
                ) from None
            note = (
                f"{folder}: took over a stale lock ({_describe(other)}: no longer running); its "
                "output may be incomplete"
            )
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            continue
        return note
    raise OutputBusyError(
        f"{what} {folder}: another selfcal took the lock at the same moment",
        fix=f"wait for it to finish, or give another {what}",
    )


@contextlib.contextmanager
def output_lock(folder: str | Path, command: str, what: str = "--out") -> Iterator[str | None]:
    """Hold ``folder``'s lock (module docstring) while the block runs; yields a note when a stale
    lock was taken over (for the user), else None. The folder is created (:func:`prepare_folder`),
    and removed again at the end when the block left it empty (a command that stopped on its
    arguments leaves no folder behind).

    Raises:
        OutputBusyError: another running process holds the lock (its pid, host, command and start
            named; a damaged lock file too: the message names it to remove).
        InputError: ``folder`` cannot be a folder (:func:`prepare_folder`).
    """
    made = not Path(folder).exists()
    folder = prepare_folder(folder, what)
    path = folder / LOCK_NAME
    mine: dict[str, object] = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "command": command,
        "started": datetime.now().astimezone().isoformat(timespec="seconds"),
    }
    ticks = _start_ticks(os.getpid())
    if ticks is not None:
        mine["start_ticks"] = ticks
    staged = write_text_atomic(folder / f"{LOCK_NAME}.{os.getpid()}", json.dumps(mine))
    try:
        note = _take(path, staged, what)
    finally:
        staged.unlink()
    try:
        yield note
    finally:
        if _read(path).get("pid") == os.getpid():
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        if made:
            with contextlib.suppress(OSError):  # not empty (the output), or gone
                folder.rmdir()
