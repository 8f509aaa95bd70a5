"""docs/cli.md is generated from the parser (`python -m selfcal.cli.docs --write`): this test
fails when a command or option changed without regenerating it."""

from __future__ import annotations

from selfcal.cli.docs import DOC, cli_markdown


def test_docs_cli_md_matches_the_parser():
    assert DOC.read_text() == cli_markdown(), (
        "docs/cli.md is stale: run `uv run python -m selfcal.cli.docs --write`"
    )


def test_every_command_is_documented_once():
    text = cli_markdown().split("## Commands")[1]
    for cmd in ("fk", "ik", "render", "acquire", "run", "calibrate", "report", "hw joints"):
        assert text.count(f"### `selfcal {cmd}`") == 1
    # hidden deprecated spellings stay out of the documentation
    assert "--model" not in text.replace("--camera-model", "") and "--rerun" not in text


def test_every_exit_code_of_check_is_in_the_table():
    from selfcal.cli.check import EXIT_CANNOT_TELL, EXIT_CHANGED

    table = cli_markdown().split("## Messages and exit codes")[1].split("## Commands")[0]
    for code in (EXIT_CHANGED, EXIT_CANNOT_TELL):
        assert f"\n| {code} | `selfcal check`" in table
