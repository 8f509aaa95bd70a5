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
