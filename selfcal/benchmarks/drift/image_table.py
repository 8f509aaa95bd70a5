"""The image drift benchmark's table (:mod:`selfcal.benchmarks.drift.images`): its rows in
Markdown (:func:`table`), read back from the docs block (:func:`parse_block`) and merged with a
run's (:func:`merge_rows`, :func:`docs_rows`), in ``docs/tool-accuracy.md``'s block
:data:`BLOCK`.
"""

from __future__ import annotations

import re

from selfcal.benchmarks.doc_blocks import ROOT, codes_note, codes_of, read_block
from selfcal.benchmarks.drift.image_checks import KINDS, NEW_VIEWS, NOISE_PX, SCENARIOS
from selfcal.config.scenario import load_scenario

__all__ = [
    "BLOCK",
    "CODE_KEYS",
    "DOC",
    "docs_rows",
    "merge_rows",
    "parse_block",
    "robots_arg",
    "table",
]

DOC = ROOT / "docs" / "tool-accuracy.md"
BLOCK = "benchmark_drift_images"
CODE_KEYS = ("setup", "noise_px")
"""The keys that name a row in the note of the code that measured it (:func:`table`)."""


def table(rows: list[dict], checks: int) -> str:
    """The Markdown table of :func:`selfcal.benchmarks.drift.images.run`'s rows."""
    head = (
        "| setup | noise (px) | calibrations | checks | 'changed' on unchanged data (target < 2 %) | "
        "0.2 mm mount shift found (target >= 95 %) | a test knowing its direction / its size / "
        "its 3 axes | "
        "named the mount / wrong | 0.05 deg joint offset found (target >= 95 %) | named the joint "
        "/ wrong | 'cannot tell' verdicts: unchanged / shift / offset |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['setup']} | {r['noise_px']:g} | {r['calibrations']} | {r['checks']} | "
        f"{100 * r['unchanged']:.1f} % | {100 * r['tool']:.1f} % | "
        f"{100 * r['tool_oracle']:.1f} % / {_size(r)} / {100 * r['tool_axes']:.1f} % | "
        f"{100 * r['tool_right']:.0f} % / {100 * r['tool_wrong']:.0f} % | "
        f"{100 * r['joint']:.1f} % | {100 * r['joint_right']:.0f} % / "
        f"{100 * r['joint_wrong']:.0f} % | {_undecided(r)} |"
        for r in rows
    ]
    failed = sum(r["failed"] for r in rows)
    views = rows[0].get("views", NEW_VIEWS)
    choose = rows[0].get("choose", 0)
    docs = views == NEW_VIEWS and not rows[0].get("exact", False) and not choose
    noise = list(dict.fromkeys(r["noise_px"] for r in rows))
    extra = "" if noise == list(NOISE_PX) else " --noise-px " + " ".join(f"{s:g}" for s in noise)
    extra += "" if views == NEW_VIEWS else f" --views {views}"
    extra += " --min-p" if rows[0].get("exact", False) else ""
    extra += f" --choose {choose}" if choose else ""
    return (head + "\n".join(lines) + f"\n\n{checks} checks per calibration ({failed} "
            f"calibrations failed in all), {views} new views per check, alpha = 0.01; "
            "a test knowing: the mean power at alpha of a test that knew the shift's direction "
            "(the most powerful), only its size, 0.2 mm of the mount's translation in a direction "
            "it is not told (the likelihood ratio averaged over the directions: no test of the "
            "mount's translation alone does better on average; - : not recorded) or only its 3 "
            "axes (their chi-square), from the check's own covariance; named: of the changes found, the share whose cause the "
            "check named (right / wrong; the rest: cause not named); 'cannot tell' verdicts: "
            "of the checks of unchanged data, of the shifted mount and of the offset joint, "
            "how many said neither 'changed' nor 'unchanged' (not counted as "
            "changed; - : not recorded). `nice -n 10 uv run python -m "
            f"selfcal.benchmarks.drift.images --calibrations {rows[0]['calibrations'] + rows[0]['failed']} "
            f"--setup {' '.join(dict.fromkeys(r['setup'].split(',')[0] for r in rows))}"
            f"{robots_arg(rows)}{extra}{' --write-docs' if docs else ''}`"
            f"{codes_note(rows, CODE_KEYS)}.")  # fmt: skip


def _size(r: dict) -> str:
    """A row's power of the test knowing the shift's size alone, "-" when its run did not
    record it."""
    return "-" if "tool_size" not in r else f"{100 * r['tool_size']:.1f} %"


def _undecided(r: dict) -> str:
    """A row's 'cannot tell' counts per kind (unchanged / shift / offset), "-" when its
    run did not record them."""
    if f"{KINDS[0]}_cannot_tell" not in r:
        return "-"
    return " / ".join(str(r[f"{k}_cannot_tell"]) for k in KINDS)


def _percent(cell: str) -> float:
    return float(cell.strip().removesuffix("%")) / 100.0


def parse_block(text: str) -> tuple[list[dict], int, int]:
    """The rows of a table :func:`table` wrote (``text``, the docs block), the calibrations
    each row asked for and the checks per calibration (from its footnote): what
    :func:`merge_rows` keeps of the rows a run did not redo."""
    asked = re.search(r"--calibrations (\d+)", text)
    per = re.search(r"(\d+) checks per calibration", text)
    if asked is None or per is None:
        raise SystemExit(f"{DOC}: the {BLOCK} block names no --calibrations or checks per "
                         "calibration: run every setup and robot to rewrite it whole")  # fmt: skip
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 11 or not cells[1].replace(".", "", 1).isdigit():
            continue  # the header, its rule, the footnote
        *oracle, axes = cells[6].split("/")
        tool_right, tool_wrong = cells[7].split("/")
        joint_right, joint_wrong = cells[9].split("/")
        rows.append({
            "setup": cells[0], "noise_px": float(cells[1]), "calibrations": int(cells[2]),
            "failed": int(asked.group(1)) - int(cells[2]), "checks": int(cells[3]),
            "unchanged": _percent(cells[4]), "tool": _percent(cells[5]),
            "tool_oracle": _percent(oracle[0]), "tool_axes": _percent(axes),
            "tool_right": _percent(tool_right), "tool_wrong": _percent(tool_wrong),
            "joint": _percent(cells[8]), "joint_right": _percent(joint_right),
            "joint_wrong": _percent(joint_wrong),
        })  # fmt: skip
        if len(oracle) == 2 and oracle[1].strip() != "-":
            rows[-1]["tool_size"] = _percent(oracle[1])
        if cells[10] != "-":
            rows[-1] |= {
                f"{k}_cannot_tell": int(n) for k, n in zip(KINDS, cells[10].split("/"), strict=True)
            }
    for r, code in zip(rows, codes_of(text, rows, CODE_KEYS), strict=True):
        if code is not None or "measured by" in text:
            r["code"] = code
    return rows, int(asked.group(1)), int(per.group(1))


def merge_rows(old: list[dict], new: list[dict]) -> list[dict]:
    """``old``'s rows with those of the same setup (robot included) and noise level replaced
    by ``new``'s, in place; ``new``'s other rows after them."""
    fresh = {(r["setup"], r["noise_px"]): r for r in new}
    out = [fresh.pop((r["setup"], r["noise_px"]), r) for r in old]
    return out + list(fresh.values())


def docs_rows(rows: list[dict], calibrations: int, checks: int) -> list[dict]:
    """The rows the docs block should hold after a run of ``rows`` (``calibrations`` asked per
    row, ``checks`` per calibration): the block's rows of the setups, robots and noise levels
    the run did not cover are kept (:func:`merge_rows`).

    Raises:
        SystemExit: the block was measured with another ``--calibrations`` or ``--checks``
            (its rows would not be alike), naming the doc and the options to give.
    """
    old, asked, per = parse_block(read_block(DOC, BLOCK))
    if (asked, per) != (calibrations, checks):
        raise SystemExit(f"{DOC}: the {BLOCK} block's rows were measured with --calibrations "
                         f"{asked} --checks {per}, this run with --calibrations {calibrations} "
                         f"--checks {checks}: give those, or run every setup and robot")  # fmt: skip
    return merge_rows(old, rows)


def robots_arg(rows: list[dict]) -> str:
    """`` --robot ...`` of the eye-in-hand rows when they are not the scenario's robot alone."""
    names = list(dict.fromkeys(r["setup"].split(", ")[1] for r in rows
                               if r["setup"].startswith("eye-in-hand")))  # fmt: skip
    default = load_scenario(SCENARIOS["eye-in-hand"]).robot.model
    return "" if names in ([], [default]) else " --robot " + " ".join(names)
