"""The local worker pool of studies and Monte Carlo (selfcal.studies.parallel): a worker's warnings
reach the command's log (printed as ``selfcal: warning:`` lines, counted in the last line) and
the workers end with their parent, even one killed by SIGTERM.

Before: a worker's warnings went raw to the shared stderr, onto the progress bar, and the last
line said "0 warnings"; `kill <montecarlo pid>` left its idle workers waiting for ever.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from selfcal.console.log import command_logging, get_logger
from selfcal.studies.parallel import run_tasks

ROOT = Path(__file__).resolve().parents[2]


def warn_and_square(item: dict) -> dict:
    """A task (imported by the spawned workers) that logs a warning."""
    get_logger("task").warning("item %d looks odd", item["x"])
    return {"x2": item["x"] ** 2}


def test_a_workers_warnings_are_logged_and_counted(capfd):
    items = [{"x": k} for k in range(3)]
    with command_logging() as log:
        rows = dict(run_tasks(warn_and_square, items, jobs=2, error_row=lambda x, e: {}))
    assert sorted(r["x2"] for r in rows.values()) == [0, 1, 4]
    err = capfd.readouterr().err.splitlines()
    assert sorted(line for line in err if "looks odd" in line) == [
        f"selfcal: warning: item {k} looks odd" for k in range(3)
    ]
    assert log.warnings == 3


POOL = """
import time
from selfcal.studies.parallel import worker_pool
if __name__ == "__main__":
    with worker_pool(2) as ex:
        for f in [ex.submit(time.sleep, 0.2) for _ in range(2)]:
            f.result()
        print(" ".join(str(p) for p in ex._processes), flush=True)
        time.sleep(60)
"""


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


def test_workers_end_when_their_parent_is_terminated(tmp_path):
    script = tmp_path / "pool.py"
    script.write_text(POOL)
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                              stderr=subprocess.DEVNULL, cwd=ROOT)  # fmt: skip
    try:
        workers = [int(p) for p in parent.stdout.readline().split()]
        assert len(workers) == 2
        parent.send_signal(signal.SIGTERM)
        parent.wait(timeout=10)
    finally:  # its pipe closed (a ResourceWarning else), the parent not left behind
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        parent.stdout.close()
    deadline = time.monotonic() + 10
    while any(map(_alive, workers)) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [p for p in workers if _alive(p)]
    for p in left:  # not to leave them behind when the test fails
        os.kill(p, signal.SIGKILL)
    assert left == []
