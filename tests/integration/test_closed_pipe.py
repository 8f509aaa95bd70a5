"""A reader that closes the output early (``selfcal scenarios | head -1``, ``| grep -q``) ends
the command quietly with 141 (128 + SIGPIPE, as a Unix tool), not "internal error ... a bug":
the CI's wheel check failed on that race (session 22)."""

from __future__ import annotations

import os
import subprocess
import sys

from selfcal.errors import EXIT_BROKEN_PIPE

CODE = "import sys; from selfcal.cli.main import script; sys.exit(script())"


def test_a_closed_stdout_ends_the_command_quietly():
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the command writes a byte
    try:
        done = subprocess.run([sys.executable, "-c", CODE, "scenarios"], stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=120)  # fmt: skip
    finally:
        os.close(write)
    assert done.returncode == EXIT_BROKEN_PIPE, done.stderr
    assert "error" not in done.stderr and "Exception ignored" not in done.stderr, done.stderr


def test_a_broken_pipe_of_the_commands_own_is_an_internal_error(capsys):
    """A BrokenPipeError that did not come from stdout (a socket or a child's pipe the command
    writes to) is a failure to report, not a reader gone: one line and 1, never a silent 141."""
    import argparse

    from selfcal.console.common import run_command
    from selfcal.errors import EXIT_INTERNAL

    def command(args):
        raise BrokenPipeError(32, "Broken pipe (a child's stdin)")

    args = argparse.Namespace(verbose=0, quiet=False)
    assert run_command(command, args) == EXIT_INTERNAL
    assert "internal error BrokenPipeError" in capsys.readouterr().err
