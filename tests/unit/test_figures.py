"""Every plot keeps its legend off the data and labels its axes; a study of one setting makes a
table, not a plot; a study where calibrating made things worse says so.

The figures are drawn from rows shaped like the real ones (``selfcal paper``'s Table IV rows, a
study's ``runs.csv`` rows), with values spread like the measured ones.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from selfcal.plots.plotting import (
    figure_problems,
    layout_problems,
    legend_outside,
    legend_overlaps,
    new_figure,
    pyplot,
    save_figure,
    stack_layout,
    unlabelled_axes,
)
from selfcal.studies.defs import STUDIES
from selfcal.studies.paper.fig3 import fig3_figure
from selfcal.studies.summary import study_figure, summarize, worse_than_nominal


def test_the_legend_check_sees_a_legend_over_data():
    """The check can fail: a legend placed on top of the data is reported."""
    plt = pyplot()
    fig, ax = plt.subplots()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="a diagonal through the middle")
    ax.legend(loc="center")
    ax.set_xlabel("x")
    try:
        assert legend_overlaps(fig) and unlabelled_axes(fig) == ["axes: x or y label missing"]
    finally:
        plt.close(fig)


def _two_panels():
    fig = new_figure(5, 4)
    for ax, name in zip(fig.subplots(2, 1), ("upper", "lower")):
        ax.plot([0.0, 1.0], [0.0, 1.0], label="a line with a long legend entry")
        ax.set(title=name, xlabel="x (m)", ylabel="y (m)")
        legend_outside(ax)
    return fig


def test_the_layout_check_sees_cut_off_and_overlapping_panels():
    """The check can fail: panels pushed to the left edge and into each other are reported;
    the same panels placed by stack_layout are not."""
    fig = _two_panels()
    fig.subplots_adjust(left=0.0, right=0.95, hspace=0.0)
    problems = layout_problems(fig)
    assert "upper: cut off at the figure's edge" in problems  # y labels and the legend
    assert "upper and lower overlap" in problems  # x label of one, title of the other
    fig = _two_panels()
    stack_layout(fig)
    assert figure_problems(fig) == []


@pytest.mark.slow  # over 2 s on 2 cores: the default tier keeps to ~90 s
def test_the_main_job_figures_need_no_pyplot(tmp_path):
    """They are drawn by every `selfcal run`: a Figure on the Agg canvas, not pyplot (issue 17);
    checked in a fresh interpreter by sys.modules."""
    probe = (
        "import json, sys\nimport numpy as np\n"
        "from selfcal.plots.job_figures import tool_tip_figure, write_figure\n"
        "e = np.random.default_rng(1).normal(size=(5, 3))\n"
        f"p = write_figure(tool_tip_figure(e, e / 100), {str(tmp_path)!r}, 'tip.png')\n"
        "print(json.dumps(['matplotlib.pyplot' in sys.modules, p.read_bytes()[:4].hex()]))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout  # fmt: skip
    assert json.loads(out.strip().splitlines()[-1]) == [False, b"\x89PNG".hex()]


def test_fig3_legends_cover_no_bar():
    rng = np.random.default_rng(1)
    rows = []
    for pos in range(1, 6):
        for ax in "xyz":
            e = rng.normal(0, 1.5)
            rows.append({
                "position": pos, "axis": f"p_{ax}",
                "paper_error_printed": e, "paper_error_recomputed": e + (pos == 2) * 0.3,
                "error_measured_minus_desired": rng.normal(0, 1.5),
                "calibrated_error_minus_true": rng.normal(0, 0.05),
                "nominal_error_desired_minus_true": rng.normal(0, 1.5),
                "camera_error_measured_minus_true": rng.normal(0, 0.1),
            })  # fmt: skip
    assert figure_problems(fig3_figure(rows)) == []


def study_rows(name: str, xs: list[float], worse_at: float | None = None) -> list[dict]:
    study = STUDIES[name]
    rows = []
    for x in xs:
        for seed in (1, 2, 3):
            cal = 0.1 * (1 + x) * (1 + 0.1 * seed)
            nom = 1.5 if x != worse_at else 0.5 * cal
            rows.append({"study": name, "key": f"{x}-{seed}", "status": "ok", study.x: x,
                         "seed": seed, "cal_rms_mm": cal, "nom_rms_mm": nom,
                         "eff_noise_px": x})  # fmt: skip
    return rows


def test_study_plot_legend_covers_no_data(tmp_path):
    rows = study_rows("noise", [0.0, 0.5, 2.0])
    res = summarize("noise", rows, tmp_path)
    assert (tmp_path / "noise.png").is_file()
    assert figure_problems(study_figure(STUDIES["noise"], res, rows)) == []


def test_study_of_one_setting_is_a_table_not_a_plot(tmp_path):
    (tmp_path / "noise.png").write_bytes(b"stale")
    summarize("noise", study_rows("noise", [0.5]), tmp_path)
    assert not (tmp_path / "noise.png").exists()
    md = (tmp_path / "noise.md").read_text()
    assert "| calibrated | 0.5 | 3 | 0 |" in md and "One setting only: a table, no plot." in md


def test_study_says_where_calibration_made_the_model_worse(tmp_path):
    rows = study_rows("noise", [0.0, 2.0], worse_at=2.0)
    res = summarize("noise", rows, tmp_path)
    worse = worse_than_nominal(STUDIES["noise"], res)
    assert len(worse) == 1 and worse[0].startswith("calibrated at pixel_sigma = 2.0")
    assert "**Warning**" in (tmp_path / "noise.md").read_text()
    assert worse_than_nominal(STUDIES["noise"], summarize("noise", rows[:3], tmp_path)) == []


@pytest.mark.parametrize("xs", [[0.25, 0.5], [1.0, 2.0, 4.0]])
def test_the_study_plot_is_drawn_from_two_settings_on(tmp_path, xs):
    summarize("perturbation", study_rows("perturbation", xs), tmp_path)
    assert (tmp_path / "perturbation.png").read_bytes()[:4] == b"\x89PNG"


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]


def test_job_figures_say_what_they_show():
    """reprojection.png's 0.120 px is a prediction from the joints, not report.md's 0.019 px
    fit; parameters.png of a board run (no sigmas) had "1 sigma" in its legend and no marks."""
    from selfcal.calibration.board.evaluate import Evaluation
    from selfcal.plots.job_figures import parameter_figure, reprojection_figure

    rng = np.random.default_rng(0)
    images = tuple({"nominal_px": 1.5 + 0.1 * k, "calibrated_px": 0.12} for k in range(6))
    ev = Evaluation(rms={"nominal": 1.6, "calibrated": 0.12}, images=images, skipped=(),
                    dataset="d", calibration="c",
                    residuals={"calibrated": rng.normal(0, 0.1, (60, 2))})  # fmt: skip
    fig = reprojection_figure(ev, "calibration images")
    assert any("predicted from the joints, not the fit's RMS" in t for t in _legend_texts(fig))
    assert figure_problems(fig) == []
    rows = [{"name": f"lx{k}", "unit": "mm", "nominal": 1.0, "estimate": 1.1 + k, "truth": 1.2,
             "std": None} for k in range(4)]  # fmt: skip
    fig = parameter_figure(rows)
    assert not any("sigma" in t for t in _legend_texts(fig))
    assert figure_problems(fig) == []
    rows[0]["std"] = 0.01
    assert any("1 sigma" in t for t in _legend_texts(parameter_figure(rows)))


def test_the_residual_histogram_separates_each_images_shift():
    """reprojection.png's u histogram was bimodal, unexplained (#32): predicted from the joints,
    every feature of an image shares one shift. The figure draws the residuals less each image's
    mean beside them, and that part is the within-image scatter."""
    from selfcal.calibration.board.evaluate import Evaluation
    from selfcal.plots.job_figures import reprojection_figure, within_image

    rng = np.random.default_rng(1)
    shift = rng.choice([-0.12, 0.12], size=(30, 2))  # one shift per image: a bimodal mixture
    e = np.repeat(shift, 20, axis=0) + rng.normal(0, 0.015, (600, 2))
    w = within_image(e, [20] * 30)
    assert w is not None and abs(float(np.std(w)) - 0.015) < 0.002
    assert within_image(e, [20] * 29) is None  # counts that do not describe e
    images = tuple({"nominal_px": 2.0, "calibrated_px": 0.12, "features": 20} for _ in range(30))
    ev = Evaluation(rms={"nominal": 2.0, "calibrated": 0.12}, images=images, skipped=(),
                    dataset="d", calibration="c", residuals={"calibrated": e})  # fmt: skip
    fig = reprojection_figure(ev, "calibration images")
    assert any("less its image's shift (std 0.01" in t for t in _legend_texts(fig))
    assert figure_problems(fig) == []


def test_a_figure_png_is_written_at_the_fast_level_with_the_same_pixels(tmp_path):
    """save_figure's PNG with options (Pillow's, zlib level 1) holds the pixels of Pillow's
    default level (6)."""
    from PIL import Image

    fig = new_figure(3.0, 2.0)
    ax = fig.add_subplot()
    ax.plot(np.arange(50), np.sin(np.arange(50) / 5.0), "o-", label="a line")
    ax.set_title("some text to draw")
    fast = save_figure(fig, tmp_path / "fast.png", pil_kwargs={"compress_level": 1})
    default = save_figure(fig, tmp_path / "default.png", pil_kwargs={})
    assert fast.read_bytes() != default.read_bytes()  # another zlib level: other bytes
    assert np.array_equal(np.asarray(Image.open(fast)), np.asarray(Image.open(default)))


@pytest.mark.parametrize("transparent", [False, True])
def test_a_figure_png_holds_the_pixels_savefig_draws(tmp_path, transparent):
    """save_figure without options writes the canvas through selfcal.io.png: the pixels of
    Pillow's savefig (RGB when all are opaque, else RGBA), at the figure's dpi; the main job's
    figures too."""
    from PIL import Image

    from selfcal.plots.job_figures import tool_tip_figure

    rng = np.random.default_rng(1)
    figs = [tool_tip_figure(rng.normal(0, 1, (20, 3)), rng.normal(0, 0.01, (20, 3)))]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(3.0, 2.0))
    ax.plot(np.arange(50), np.sin(np.arange(50) / 5.0), "o-", label="a line")
    ax.set_title("some text to draw")
    figs.append(fig)
    for k, fig in enumerate(figs):
        if transparent:
            fig.patch.set_alpha(0.0)
        ours = save_figure(fig, tmp_path / f"ours{k}.png")
        pillow = save_figure(fig, tmp_path / f"pillow{k}.png", pil_kwargs={})
        with Image.open(ours) as a, Image.open(pillow) as b:
            assert a.mode == ("RGBA" if transparent else "RGB")
            assert a.info["dpi"] == pytest.approx(b.info["dpi"], abs=0.01)
            assert np.array_equal(np.asarray(a.convert("RGBA")), np.asarray(b.convert("RGBA")))
        plt.close(fig)


def test_the_figures_text_is_drawn_unhinted_and_no_one_elses():
    """save_figure draws the project's figures with TEXT_HINTING (matplotlib reads it at each
    text it measures or draws), whatever the process's setting is: a text then draws other
    pixels than with FreeType's default hinting. new_figure and pyplot set it process-wide
    before, so a program importing selfcal.plots had its own figures unhinted (review of
    session 28); now the setting is the program's before, between and after."""
    import io

    import matplotlib
    from PIL import Image

    from selfcal.plots.plotting import TEXT_HINTING, figure_png

    def fig_with_text():
        fig = new_figure(2.0, 1.0)
        fig.text(0.1, 0.5, "validation posture 0.010 mm")
        return fig

    assert TEXT_HINTING != "default"
    with matplotlib.rc_context({"text.hinting": "default"}):
        pyplot()
        ours = np.asarray(Image.open(io.BytesIO(figure_png(fig_with_text()))))
        assert matplotlib.rcParams["text.hinting"] == "default"
        buf = io.BytesIO()
        fig_with_text().savefig(buf, format="png")  # a figure drawn by the program itself
        theirs = np.asarray(Image.open(buf))
        assert matplotlib.rcParams["text.hinting"] == "default"
        with matplotlib.rc_context({"text.hinting": TEXT_HINTING}):
            buf = io.BytesIO()
            fig_with_text().savefig(buf, format="png")
            unhinted = np.asarray(Image.open(buf))
    assert np.array_equal(ours[..., :3], unhinted[..., :3])
    assert not np.array_equal(ours[..., :3], theirs[..., :3])
