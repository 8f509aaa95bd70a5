"""Every "the code at X" in README.md and docs/*.md, a generated block's or the prose's, names a
commit of HEAD's history: the writers refuse such a block (doc_blocks.stamp_problems), but
docs/plan.md's prose named a branch's commit that its rebase replaced ("measured by the code at
4819170", review of session 28, finding 5)."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from selfcal.benchmarks.doc_blocks import ROOT, STAMP, stamp_problems

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _shallow() -> bool:
    """True when the checkout lacks history (a shallow clone): no stamp can be checked."""
    out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--is-shallow-repository"],
                         capture_output=True, text=True)  # fmt: skip
    return out.returncode != 0 or out.stdout.strip() != "false"


@pytest.mark.skipif(shutil.which("git") is None or _shallow(), reason="needs git's history")
def test_every_stamp_in_the_docs_names_a_commit_of_the_history():
    assert sum(len(STAMP.findall(p.read_text())) for p in DOCS) > 0  # the pattern still reads
    bad = {p.name: stamp_problems(p.read_text()) for p in DOCS}
    assert {k: v for k, v in bad.items() if v} == {}
