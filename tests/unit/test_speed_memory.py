"""The speed benchmark's peak memory of a command is the command's own, not its parent's."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from selfcal.benchmarks.child import run_child

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ru_maxrss in kB")


def test_a_small_command_beside_a_large_parent_reports_its_own_size() -> None:
    big = np.ones(300 * 2**20 // 8)  # 300 MB resident in this process
    code, _, mb = run_child([sys.executable, "-c", "pass"])
    assert big[-1] == 1.0
    assert code == 0
    assert mb < 100  # a bare interpreter is ~10-20 MB; fork-inherited would be >= 300


def test_a_command_that_grows_reports_its_peak_and_exit_code() -> None:
    grow = "import numpy as np, sys; a = np.ones(200 * 2**20 // 8); sys.exit(3)"
    code, _, mb = run_child([sys.executable, "-c", grow])
    assert code == 3
    assert 200 <= mb < 400


def test_the_command_s_standard_error_goes_to_the_file_given(tmp_path) -> None:
    err = tmp_path / "stderr.txt"
    code, wall, _ = run_child([sys.executable, "-c", "import sys; sys.stderr.write('said')"],
                              stderr=err)  # fmt: skip
    assert code == 0 and wall > 0
    assert err.read_text() == "said"
