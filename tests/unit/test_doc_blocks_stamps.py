"""The code stamps of the docs' generated blocks (selfcal.benchmarks.doc_blocks): a block is
never written naming code no one can check out (uncommitted changes, or a commit outside HEAD's
history, as a branch's commit its rebase replaced: review of session 23), only the package's
changes make the code "+changes", and "code that is not recoverable" reads back as written."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from selfcal.benchmarks import doc_blocks
from selfcal.benchmarks.doc_blocks import (
    UNRECOVERABLE,
    code_version,
    codes_note,
    codes_of,
    stamp_problems,
    write_block,
)

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="needs git")


def _git(root, *args: str) -> str:
    return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                          check=True).stdout.strip()  # fmt: skip


@pytest.fixture
def repo(tmp_path):
    """A checkout with two commits on its branch and one on a side branch (the commit a rebase
    would replace): (root, first, head, side) short hashes."""
    _git(tmp_path, "init", "-q", "-b", "main")
    _git(tmp_path, "config", "user.email", "t@t")
    _git(tmp_path, "config", "user.name", "t")
    (tmp_path / "selfcal").mkdir()
    (tmp_path / "docs").mkdir()
    shas = []
    for i in range(2):
        (tmp_path / "selfcal" / "a.py").write_text(f"x = {i}\n")
        (tmp_path / "docs" / "a.md").write_text(f"{i}\n")
        _git(tmp_path, "add", "-A")
        _git(tmp_path, "commit", "-qm", f"c{i}")
        shas.append(_git(tmp_path, "rev-parse", "--short=7", "HEAD"))
    _git(tmp_path, "checkout", "-qb", "side")
    (tmp_path / "selfcal" / "a.py").write_text("x = 9\n")
    _git(tmp_path, "commit", "-qam", "side")
    side = _git(tmp_path, "rev-parse", "--short=7", "HEAD")
    _git(tmp_path, "checkout", "-q", "main")
    return tmp_path, shas[0], shas[1], side


def test_a_stamp_names_code_that_can_be_checked_out(repo):
    root, first, head, side = repo
    assert stamp_problems(f"measured by the code at {head} and the code at {first}", root) == []
    got = stamp_problems(
        f"Measured by the code at {head}+changes, the code at {side} and the code at 0123abc", root
    )
    assert got == [f"{head}+changes (uncommitted changes)",
                   f"{side} (not a commit of HEAD's history)",
                   "0123abc (not a commit of HEAD's history)"]  # fmt: skip


def test_only_the_package_changes_the_code(repo):
    """The docs being written are not the code's change; the package's files are, a new one
    too."""
    root, _, head, _ = repo
    (root / "docs" / "a.md").write_text("prose\n")
    assert code_version(root) == head
    (root / "selfcal" / "b.py").write_text("y = 1\n")
    assert code_version(root) == f"{head}+changes"


@pytest.mark.parametrize(
    "path", ["models/arm/robot.toml", "scenarios/cell.toml", "tests/data/arm7.toml", "uv.lock"]
)
def test_the_data_the_benchmarks_read_is_the_code_too(repo, path):
    """A robot model, a scenario or the test data a benchmark reads (a shipped arm, a cell,
    arm7, the real sets) edited after the commit make its draws another code's (review of
    session 24: an edited robot TOML kept a clean stamp); a test's change does not."""
    root, _, head, _ = repo
    (root / "tests" / "unit").mkdir(parents=True)
    (root / "tests" / "unit" / "test_a.py").write_text("def test(): pass\n")
    assert code_version(root) == head
    (root / path).parent.mkdir(parents=True, exist_ok=True)
    (root / path).write_text("x = 1\n")
    assert code_version(root) == f"{head}+changes"


@pytest.mark.skipif(code_version() is None, reason="the project is not a git checkout here")
@pytest.mark.parametrize("stamp", ["0123abc", "HEAD+changes"])
def test_a_block_naming_code_that_cannot_be_checked_out_is_not_written(tmp_path, stamp):
    head = code_version().removesuffix("+changes")
    doc = tmp_path / "doc.md"
    before = "x\n<!-- b: begin -->\nold\n<!-- b: end -->\n"
    doc.write_text(before)
    block = f"| 1 |\n\n`cmd --write-docs`, measured by the code at {stamp.replace('HEAD', head)}."
    with pytest.raises(SystemExit, match="cannot be checked out") as e:
        write_block(doc, block, "b")
    assert "not written" in str(e.value) and doc.read_text() == before
    write_block(doc, f"| 1 |\n\nmeasured by the code at {head}.", "b")
    assert f"the code at {head}." in doc.read_text()


def test_code_that_is_not_recoverable_reads_back_as_written():
    rows = [{"setup": "a", "code": None}, {"setup": "b", "code": UNRECOVERABLE},
            {"setup": "c", "code": "abc1234"}]  # fmt: skip
    note = codes_note(rows, ("setup",))
    assert note == (", measured by an earlier code, not recorded (a), code that is not "
                    "recoverable (b) and the code at abc1234 (c)")  # fmt: skip
    assert codes_of(f"table{note}.", rows, ("setup",)) == [None, UNRECOVERABLE, "abc1234"]
    one = codes_note(rows[1:2], ("setup",))
    assert one == ", measured by code that is not recoverable"
    assert codes_of(f"table{one}.", rows[1:2], ("setup",)) == [UNRECOVERABLE]
    assert doc_blocks.stamp_problems(one) == []  # no stamp for a writer to refuse
