"""The speed benchmark's tables (:mod:`selfcal.benchmarks.speed.measure`): the block README.md and
docs/performance.md show, and the check of a new block against the README's (#17: a figure more
than :data:`TOLERANCE` off is named)."""

from __future__ import annotations

import datetime
import os
import re
import shlex
import statistics

from selfcal.benchmarks.doc_blocks import ROOT

__all__ = [
    "TOLERANCE",
    "check",
    "command_text",
    "figures_of",
    "linear_growth",
    "load_text",
    "readme_block",
    "table",
]

BEGIN, END = "<!-- benchmark_speed: begin -->", "<!-- benchmark_speed: end -->"
TOLERANCE = 1.3
COMMAND = (
    "MUJOCO_GL=egl uv run python -m selfcal.benchmarks.speed.measure --write-docs --write-readme"
)


def load_text(values: list[float]) -> str:
    """1-minute load averages for a table: each reading, or past eight their range and
    median."""
    if len(values) <= 8:
        return ", ".join(f"{v:.1f}" for v in values)
    return (f"{min(values):.1f}-{max(values):.1f}, median {statistics.median(values):.1f} over "
            f"{len(values)} readings")  # fmt: skip


def command_text(argv: list[str]) -> str:
    """The command that measured a table: this module with ``argv``."""
    return f"MUJOCO_GL=egl uv run python -m selfcal.benchmarks.speed.measure {shlex.join(argv)}".strip()


def table(fig: dict, command: str = COMMAND) -> str:
    """The Markdown block (README and docs/performance.md). ``fig`` with ``rounds``: the
    medians of that many rounds measured in turn with another tree (``--against``)."""
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    how = (f"each figure the median of {fig['rounds']} rounds, interleaved part by part with the "
           "other tree below; " if "rounds" in fig else "")  # fmt: skip
    lines = [
        f"Measured {when} with `{command}` ({os.cpu_count()} CPUs; {how}1-minute load average "
        f"during the parts: {load_text(fig['load'])}; 1 BLAS thread).",
        "",
        "| what | seconds |",
        "|---|---|",
        f"| `selfcal --help` (process, median; CPU {fig['help'][1]:.2f} s) | {fig['help'][0]:.2f} |",
        f"| `selfcal fk --joints ...` (process, median; CPU {fig['fk'][1]:.2f} s) | "
        f"{fig['fk'][0]:.2f} |",
    ]
    if "run" in fig:
        lines.append(f"| `selfcal run` default scenario (rendered, 30 poses; process, median; CPU "
                     f"{fig['run'][1]:.2f} s) | {fig['run'][0]:.2f} |")  # fmt: skip
    if "run_loaded" in fig:
        r = fig["run_loaded"][0] / fig["run"][0]
        lines.append(f"| same, beside a CPU-bound process (CPU {fig['run_loaded'][1]:.2f} s; "
                     f"{r:.2f}x the quiet run) | {fig['run_loaded'][0]:.2f} |")  # fmt: skip
    for r in fig["calibrate"]:
        lines.append(
            f"| `calibrate`, analytic, {r['poses']} poses ({r['used']} used; in-process wall, "
            f"CPU {r['cpu']:.2f} s, {1000 * r['wall'] / r['poses']:.0f} ms/pose) | "
            f"{r['wall']:.2f} |"
        )
    for r in fig["calibrate"]:
        lines.append(f"| acquisition, analytic, {r['poses']} poses | {r['acquire']:.2f} |")
    b = fig["ba"]
    lines += [
        f"| bundle adjustment, {b['poses']} poses ({b['unknowns']} unknowns), engine "
        f"({b['solver']}; cost {b['engine_cost']:.6g}) | {b['engine']:.2f} |",
        f"| same, `scipy.optimize.least_squares` trf + lsmr, sparse Jacobian (cost "
        f"{b['scipy_cost']:.6g}; {b['scipy'] / b['engine']:.1f}x the engine's time) | "
        f"{b['scipy']:.2f} |",
    ]
    if "pybotics" in fig:
        lines += _pybotics_lines(fig["pybotics"])
    return "\n".join(lines)


def _pybotics_lines(r: dict) -> list[str]:
    """The identification rows: ours, and pybotics with the ratio (or why it is missing)."""
    what = f"identification from tracker positions, UR5e, {r['N']} configurations"
    lines = [
        f"| {what}: ours (`identify_tracker`, best of 10; CPU {r['ours_cpu_s']:.4f} s; "
        f"held-out {r['ours_mm']:.3f} mm) | {r['ours_s']:.4f} |"
    ]
    if r["pyb_s"] is None:
        return lines + [f"| same, pybotics: not measured ({r['note']}) | n/a |"]
    return lines + [
        f"| same, {r['note']} `least_squares` in its own environment (best of 3; CPU "
        f"{r['pyb_cpu_s']:.3f} s; held-out {r['pyb_mm']:.3f} mm; {r['pyb_s'] / r['ours_s']:.0f}x "
        f"ours' time, {r['pyb_cpu_s'] / r['ours_cpu_s']:.0f}x by CPU) | {r['pyb_s']:.3f} |"
    ]


def figures_of(text: str) -> dict[str, float]:
    """``what -> seconds`` of a table written by :func:`table` (for --check)."""
    out = {}
    for m in re.finditer(r"^\| (.+?) \| ([0-9.]+) \|$", text, flags=re.M):
        key = re.sub(r"\(.*?\)|cost [0-9.e+-]+|[0-9.]+x", "", m.group(1)).strip()
        out[key] = float(m.group(2))
    return out


def readme_block() -> str:
    text = (ROOT / "README.md").read_text()
    if BEGIN not in text or END not in text:
        return ""
    return text.split(BEGIN, 1)[1].split(END, 1)[0]


def check(new: str, stated: str | None = None) -> list[str]:
    """Figures of the table ``new`` more than TOLERANCE off (either way) those of ``stated``
    (default: the README's block), one sentence each."""
    old = figures_of(readme_block() if stated is None else stated)
    bad = []
    for k, v in figures_of(new).items():
        if k in old and old[k] > 0 and v > 0:
            r = v / old[k]
            if r > TOLERANCE or r < 1 / TOLERANCE:
                bad.append(f"{k}: measured {v:.2f} s, README {old[k]:.2f} s ({r:.2f}x)")
    return bad


def linear_growth(rows: list[dict]) -> str:
    """How `calibrate`'s time grows from the first to the last pose count (1.0 = linear)."""
    a, b = rows[0], rows[-1]
    return (
        f"calibrate {a['poses']} -> {b['poses']} poses: time x{b['wall'] / a['wall']:.1f} "
        f"(wall), x{b['cpu'] / a['cpu']:.1f} (CPU) for poses x{b['poses'] / a['poses']:.1f}"
    )
