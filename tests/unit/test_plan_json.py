"""plan.json's one writer and one reader (selfcal/io/plan_files.py): the header first, in the
order every ``selfcal plan`` wrote it, and a file of another format, a newer schema or another
kind refused with the file, the key and the fix."""

from __future__ import annotations

import json

import pytest

from selfcal.errors import InputError, UsageError
from selfcal.io.jsonfile import write_report
from selfcal.io.plan_files import PLAN_SCHEMA_VERSION, read_plan, write_plan


def test_the_header_comes_first_and_the_file_reads_back(tmp_path):
    path = tmp_path / "plan.json"
    doc = write_plan(path, "tracker", {"robot": "ur5e", "count": 3, "tool_point_mm": [0, 0, 50]})
    text = path.read_text()
    assert text.startswith('{\n "format": "scorbot-selfcal-plan",\n "schema_version": 1,\n'
                           ' "kind": "tracker",\n "robot": "ur5e",\n "count": 3,')  # fmt: skip
    assert json.loads(text) == doc and list(doc) == list(json.loads(text))
    assert read_plan(path) == doc
    assert read_plan(path, ("tracker",)) == doc


def _write(path, **header) -> None:
    doc = {"format": "scorbot-selfcal-plan", "schema_version": 1, "kind": "camera", "count": 6}
    doc.update(header)
    path.write_text(json.dumps({k: v for k, v in doc.items() if v is not None}))


@pytest.mark.parametrize(
    ("header", "says", "fix"),
    [
        ({"format": "scorbot-selfcal-report"}, "not a scorbot-selfcal-plan file", "selfcal plan"),
        ({"format": None}, "not a scorbot-selfcal-plan file (format = None)", "selfcal plan"),
        ({"schema_version": PLAN_SCHEMA_VERSION + 1},
         f"schema_version {PLAN_SCHEMA_VERSION + 1} is newer", "upgrade scorbot-selfcal"),
        ({"schema_version": "1"}, "schema_version must be a positive integer", "selfcal plan"),
        ({"kind": None}, "missing key 'kind'", "selfcal plan"),
        ({"kind": 3}, "key 'kind' must be a string", "selfcal plan"),
        ({"kind": "survey"}, "key 'kind' is 'survey', which this scorbot-selfcal does not know",
         "upgrade scorbot-selfcal"),
        ({"kind": "tracker"}, "key 'kind' is 'tracker'; a plan of kind camera or add is read here",
         "of kind camera or add"),
    ],
    ids=["report", "no-format", "newer", "version-text", "no-kind", "kind-number",
         "unknown-kind", "other-kind"],
)  # fmt: skip
def test_another_format_version_or_kind_is_refused(tmp_path, header, says, fix):
    path = tmp_path / "plan.json"
    _write(path, **header)
    with pytest.raises(InputError) as e:
        read_plan(path, ("camera", "add"))
    assert e.value.message.startswith(f"{path}: ") and says in e.value.message
    assert e.value.fix is not None and fix in e.value.fix


def test_a_report_is_not_a_plan(tmp_path):
    path = write_report(tmp_path / "report.json", {"kind": "fit"})
    with pytest.raises(InputError, match="not a scorbot-selfcal-plan file"):
        read_plan(path)


@pytest.mark.parametrize("text", ["", "[1, 2]", "{"], ids=["empty", "list", "cut"])
def test_a_file_that_is_no_json_object_is_refused(tmp_path, text):
    path = tmp_path / "plan.json"
    path.write_text(text)
    with pytest.raises(InputError, match="plan.json: not"):
        read_plan(path)


def test_a_missing_file_is_refused(tmp_path):
    with pytest.raises(InputError, match="cannot be read"):
        read_plan(tmp_path / "plan.json")


@pytest.mark.parametrize(
    ("kind", "body"),
    [("survey", {}), ("camera", {"kind": "add"}), ("camera", {"schema_version": 2})],
)
def test_the_writer_refuses_an_unknown_kind_or_a_header_in_the_body(tmp_path, kind, body):
    with pytest.raises(UsageError):
        write_plan(tmp_path / "plan.json", kind, body)
    assert not (tmp_path / "plan.json").exists()
