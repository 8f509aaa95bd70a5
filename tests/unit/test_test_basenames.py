"""Every test module's file name is unique across the tiers.

The test folders are not packages (pytest's rootdir import mode), so two files named alike in
``tests/unit`` and ``tests/integration`` cannot be collected in one session: the default tier
passes and the whole run (CI's collect-only step, ``pytest -m "slow or not slow"``) stops with
"import file mismatch". Session 30's tracker ``--add`` tests met it.
"""

from collections import Counter
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]


def test_test_module_names_are_unique() -> None:
    names = Counter(path.name for path in TESTS.rglob("test_*.py") if ".venv" not in path.parts)
    assert len(names) > 100, "the tests folder was not found"
    shared = sorted(name for name, count in names.items() if count > 1)
    assert not shared, f"test modules sharing a name (rename one): {shared}"
