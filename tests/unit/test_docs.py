"""The README and docs/*.md say only what runs: every code block that is a command or a config
is parsed (TOML by its reader: a scenario by `load_scenario`, a target by `parse_target`; every
`selfcal ...` line by the real argparse parser), the cheap commands of the README's command table
are run, and the docs cite nothing outside the repository.

Every fenced block names its kind: ``toml`` (a config), ``sh`` (commands), ``text`` (output,
diagrams), ``python`` or ``json`` (examples of code and file contents).
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from selfcal.acquisition.hardware import scenario_settings
from selfcal.cli.main import build_parser, main
from selfcal.config.scenario import load_scenario
from selfcal.io.target_toml import parse_target
from selfcal.tomlfile import parse_toml

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
KINDS = ("toml", "sh", "text", "python", "json")
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def blocks(kind: str) -> list[tuple[str, str]]:
    """``(where, body)`` of every fenced block of ``kind`` in the docs."""
    out = []
    for doc in DOCS:
        text = doc.read_text()
        for m in FENCE.finditer(text):
            if m.group(1) == kind:
                line = text[: m.start()].count("\n") + 1
                out.append((f"{doc.relative_to(ROOT)}:{line}", m.group(2)))
    return out


def test_every_block_names_its_kind():
    untagged = [
        f"{doc.relative_to(ROOT)}: ```{m.group(1)}"
        for doc in DOCS
        for m in FENCE.finditer(doc.read_text())
        if m.group(1) not in KINDS
    ]
    assert untagged == []


@pytest.mark.parametrize(("where", "body"), blocks("toml"), ids=lambda v: str(v)[:40])
def test_toml_blocks_are_read_by_their_reader(where, body, tmp_path):
    doc = parse_toml(body, where)
    if "type" in doc:
        parse_target(doc, where)  # a target TOML (docs/targets.md)
        return
    # as a file of scenarios/ beside the repository's models/ (a [target] board is relative)
    (tmp_path / "models").symlink_to(ROOT / "models")
    path = tmp_path / "scenarios" / "scenario.toml"
    path.parent.mkdir()
    path.write_text(body)
    s = load_scenario(path)
    if s.robot.backend == "hardware":  # checked as `selfcal acquire` does before opening the port
        scenario_settings(s)


def commands() -> list[tuple[str, list[str]]]:
    """Every ``selfcal`` command line of the ``sh`` blocks (after ``uv run`` and environment
    assignments; continuation lines joined; comments dropped)."""
    out = []
    for where, body in blocks("sh"):
        for line in body.replace("\\\n", " ").splitlines():
            argv = shlex.split(line, comments=True)
            while argv and re.fullmatch(r"\w+=.*", argv[0]):
                argv = argv[1:]
            if argv[:2] == ["uv", "run"]:
                argv = argv[2:]
            if argv[:1] == ["selfcal"]:
                out.append((where, argv[1:]))
    return out


@pytest.mark.parametrize(("where", "argv"), commands(), ids=lambda v: str(v)[:50])
def test_selfcal_lines_parse(where, argv):
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            build_parser().parse_args(argv)
        except SystemExit:
            pytest.fail(f"{where}: selfcal {shlex.join(argv)}: {err.getvalue()}")


def table_commands(name: str) -> list[list[str]]:
    """The README command table's ``selfcal NAME ...`` examples without placeholders."""
    text = (ROOT / "README.md").read_text()
    found = re.findall(r"^\| `selfcal (" + name + r" [^`]*)`", text, re.M)
    return [shlex.split(c) for c in found if "..." not in c and "|" not in c]


@pytest.mark.parametrize("argv", table_commands("fk") + table_commands("ik"), ids=" ".join)
def test_readme_table_fk_and_ik_examples_run(argv, capsys):
    assert main(argv) == 0
    assert capsys.readouterr().out.startswith("{")


def test_there_are_commands_to_check():
    assert len(commands()) >= 15 and len(table_commands("fk") + table_commands("ik")) >= 3


OUTSIDE = re.compile(r"^\.\./|/\.\./|/work/|\.library|^shared/")


def repository_folders(root: Path) -> set[str]:
    """The top-level folders of the checkout ``root`` that hold repository files: not hidden,
    and not a generated output folder that ``.gitignore`` names (``runs/``, which ``selfcal
    run`` writes: a path under it in the docs is an output, not a repository path)."""
    ignore = root / ".gitignore"
    lines = ignore.read_text().splitlines() if ignore.exists() else []
    outputs = {ln.strip().strip("/") for ln in lines if re.fullmatch(r"/?[\w.-]+/", ln.strip())}
    return {p.name for p in root.iterdir()
            if p.is_dir() and not p.name.startswith(".") and p.name not in outputs}  # fmt: skip


def test_output_folders_are_not_repository_folders(tmp_path):
    for name in ("docs", "runs", "out", ".venv"):
        (tmp_path / name).mkdir()
    (tmp_path / ".gitignore").write_text("__pycache__/\n*.pyc\n.venv/\nruns/\nout/\n")
    assert repository_folders(tmp_path) == {"docs"}
    assert "runs" not in repository_folders(ROOT) and "selfcal" in repository_folders(ROOT)


def test_docs_cite_nothing_outside_the_repository():
    """No link leaves the repository (no web page, no sibling folder); every repository path
    named in backticks exists (a path under an output folder, :func:`repository_folders`, is
    what a command writes)."""
    tops = repository_folders(ROOT)
    bad = []
    for doc in DOCS:
        prose = FENCE.sub("", doc.read_text())
        for target in re.findall(r"\]\(([^)\s]+)\)", prose):
            path = target.split("#")[0]
            if re.match(r"\w+://", path) or OUTSIDE.search(path):
                bad.append(f"{doc.name}: link {target}")
            elif path and not (doc.parent / path).exists():
                bad.append(f"{doc.name}: link {target} (no such file)")
        for path in re.findall(r"`([\w.-]+(?:/[\w.-]+)+)`", prose):
            first = path.split("/")[0]
            if OUTSIDE.search(path) or (first in tops and not (ROOT / path).exists()):
                bad.append(f"{doc.name}: `{path}` is not in the repository")
    assert bad == []


def _evaluate_lines() -> list[tuple[str, list[str]]]:
    """Every ``selfcal evaluate`` line of the docs' ``sh`` blocks and of the real sets' READMEs
    (tests/data/real/*/README.md: a user runs them as written)."""
    found = [(w, a) for w, a in commands() if a[:1] == ["evaluate"]]
    for readme in sorted((ROOT / "tests/data/real").glob("*/README.md")):
        text = readme.read_text()
        for m in FENCE.finditer(text):
            for line in m.group(2).replace("\\\n", " ").splitlines():
                argv = shlex.split(line, comments=True)
                if argv[:2] == ["selfcal", "evaluate"]:
                    found.append((str(readme.relative_to(ROOT)), argv[1:]))
    return found


def test_evaluate_lines_write_where_report_and_export_read():
    """`selfcal evaluate CAL DATASET2 --out FILE` is used by report and export only as
    CAL/evaluation.json: every such line in the docs and the real sets' READMEs writes there or
    gives no --out (the READMEs said `--out ev.json`, which neither reads: new user's trip,
    session 25)."""
    lines = _evaluate_lines()
    readmes = [w for w, _ in lines if w.startswith("tests/data/real")]
    assert len(readmes) >= 2, lines  # photoneo's and ical-charuco's (mecheye's points to them)
    for where, argv in lines:
        args = build_parser().parse_args(argv)
        if args.out is not None:
            assert Path(args.out) == Path(args.calibration) / "evaluation.json", (where, argv)


def test_the_readme_table_s_evaluate_writes_where_report_and_export_read():
    """The README's command table gave `selfcal evaluate CALIBRATION_DIR DATASET2` with its
    output `DATASET2/evaluation.json`, which report and export do not read (new user's trip,
    session 26: the command's own note then names the --out): the row gives the --out."""
    rows = [r for r in (ROOT / "README.md").read_text().splitlines()
            if r.startswith("| `selfcal evaluate ")]  # fmt: skip
    assert len(rows) == 1, rows
    argv = shlex.split(rows[0].split("`")[1])[1:]
    args = build_parser().parse_args(argv)
    assert args.out is not None and Path(args.out) == Path(args.calibration) / "evaluation.json"
