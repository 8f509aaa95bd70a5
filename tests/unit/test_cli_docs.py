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


def test_every_command_that_always_prints_json_accepts_json():
    """The grammar says `fk`, `ik`, `render`, `export` and `hw` always print JSON and `--json` is
    the one spelling of it: `selfcal export DIR --format opencv --json` was refused with
    "unrecognized arguments: --json" (session 25's new-user trip)."""
    import argparse

    from selfcal.cli.main import build_parser

    grammar = cli_markdown().split("## Grammar")[1].split("##")[0]
    assert "`fk`, `ik`, `render`, `export` and `hw` always print JSON" in grammar
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    hw = next(a for a in sub.choices["hw"]._actions if isinstance(a, argparse._SubParsersAction))
    parsers = {name: sub.choices[name] for name in ("fk", "ik", "render", "export")}
    parsers.update({f"hw {name}": p for name, p in hw.choices.items()})
    for name, p in parsers.items():
        flags = {s for a in p._actions for s in a.option_strings}
        assert "--json" in flags, f"selfcal {name} lacks --json"


def test_evaluate_out_says_where_report_reads_it():
    """`selfcal evaluate --out`'s help said only its default (the held-out dataset), where
    `selfcal report` and `export` never look (session 25's new-user trip)."""
    text = cli_markdown().split("### `selfcal evaluate`")[1].split("### `selfcal")[0]
    assert "selfcal report and export read CALIBRATION/evaluation.json" in " ".join(text.split())
