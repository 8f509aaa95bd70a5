"""The figures of the main job (``selfcal run``, ``calibrate``, ``report``) in ``DIR/figures/``.

- ``tool_tip_errors.png`` (simulation: needs the truth): per validation posture the tool-tip
  error of the nominal and the calibrated model after the best rigid alignment, and the
  calibrated error's x, y, z components -- the paper's Fig. 3 for the held-out postures;
- ``reprojection.png``: every image of the dataset predicted from its joint reading alone
  (:func:`selfcal.calibration.field.evaluate.evaluate_field` / :func:`selfcal.calibration.board.evaluate.evaluate_board`): the
  RMS per image of the calibrated model and of the nominal reference, and the histogram of the
  calibrated model's residuals (u, v) beside the same residuals less each image's mean: predicted
  from the joint readings alone, every feature of an image shares one shift (the reading's error
  moves the whole view), so the histogram is a mixture of a few dozen per-posture shifts and can
  look bimodal; what is left within an image is the fit's pixel error;
- ``parameters.png`` (simulation): every minimal parameter's ``|estimate - truth|`` beside its
  1-sigma and ``|nominal - truth|`` (mm and deg in two panels).

Legends sit outside the data (:func:`selfcal.plots.plotting.legend_outside`). Every ``selfcal run``
draws them, so they are built without pyplot and laid out at fixed margins
(:func:`selfcal.plots.plotting.new_figure`, :func:`selfcal.plots.plotting.stack_layout`): one draw per
file, where ``constrained_layout`` drew each twice (issue 17). Titles sit at ``y=1.0`` (where
matplotlib would put them above bottom ticks anyway): a title placed by matplotlib measures
the axes' ticks again before each draw.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from selfcal.plots.plotting import (
    close_figure,
    legend_outside,
    log_y,
    new_figure,
    save_figure,
    stack_layout,
)

if TYPE_CHECKING:  # the calibration's import (0.6 s) is not this module's: see ReprojectionData
    from selfcal.calibration.board.evaluate import Evaluation

__all__ = [
    "FIGURES",
    "tool_tip_figure",
    "ReprojectionData",
    "reprojection_figure",
    "parameter_figure",
    "write_figure",
]

FIGURES = "figures"
"""The folder of the figures inside a dataset folder."""


def tool_tip_figure(nominal_mm: np.ndarray, calibrated_mm: np.ndarray) -> Any:
    """Per validation posture (m of them): ``|error|`` of both models (log scale) and the
    calibrated error's components; ``nominal_mm``, ``calibrated_mm`` (m, 3) mm after alignment."""
    nom, cal = np.linalg.norm(nominal_mm, axis=1), np.linalg.norm(calibrated_mm, axis=1)
    k = np.arange(1, len(nom) + 1)
    fig = new_figure(9, 7)
    a1, a2 = fig.subplots(2, 1)
    w = 0.38
    a1.bar(k - w / 2, nom, w, color="0.55", label=f"nominal ({_rms(nom):.3f} mm RMS)")
    a1.bar(k + w / 2, cal, w, color="tab:red", label=f"calibrated ({_rms(cal):.3f} mm RMS)")
    log_y(a1)
    a1.set_ylabel("|tool-tip error| (mm, log)")
    a1.set_xlabel("validation posture")
    a1.set_xticks(k)
    a1.set_title("(a) tool-tip error per validation posture, nominal and calibrated model", y=1.0)
    a1.grid(axis="y", alpha=0.3, which="both")
    legend_outside(a1)
    w3 = 0.26
    for j, (ax_name, c) in enumerate(zip("xyz", ("tab:blue", "tab:orange", "tab:green"))):
        a2.bar(k + (j - 1) * w3, calibrated_mm[:, j], w3, color=c, label=f"p_{ax_name}")
    a2.axhline(0.0, color="k", lw=0.6)
    a2.set_ylabel("calibrated error (mm)")
    a2.set_xlabel("validation posture (held out, never used to calibrate)")
    a2.set_title("(b) calibrated model - truth per axis", y=1.0)
    a2.set_xticks(k)
    a2.grid(axis="y", alpha=0.3)
    legend_outside(a2)
    fig.suptitle("Tool-tip errors after the best rigid alignment (as the paper's Fig. 3)",
                 y=1.0 - 0.06 / 7, va="top")  # fmt: skip
    stack_layout(fig, top=0.6)
    return fig


def within_image(e: np.ndarray, counts: list[int]) -> np.ndarray | None:
    """The residuals ``e`` (k, 2) px, image after image with ``counts`` features each, less each
    image's mean (the shift the joint reading's error gives the whole view); None when the counts
    do not describe ``e``."""
    counts_a = np.asarray(counts, dtype=np.int64)
    if len(e) == 0 or counts_a.sum() != len(e) or (counts_a <= 0).any():
        return None
    image = np.repeat(np.arange(len(counts_a)), counts_a)
    mean = np.zeros((len(counts_a), 2))
    np.add.at(mean, image, e)
    return e - (mean / counts_a[:, None])[image]


@dataclass(frozen=True)
class ReprojectionData:
    """What :func:`reprojection_figure` draws of an :class:`Evaluation`: its ``rms`` by model
    (px), ``images`` (rows with ``nominal_px``, ``calibrated_px``, ``features``) and
    ``residuals`` by model ((k, 2) px). Pickled to the figure worker
    (:mod:`selfcal.plots.figure_pool`), which is forked before the calibration is imported and
    need not import it to unpickle these."""

    rms: dict[str, float]
    images: tuple[dict, ...]
    residuals: dict[str, np.ndarray]

    @classmethod
    def of(cls, ev: Evaluation) -> ReprojectionData:
        """The parts of ``ev`` the figure draws."""
        return cls(dict(ev.rms), tuple(ev.images), dict(ev.residuals))


def reprojection_figure(ev: Evaluation | ReprojectionData, what: str) -> Any:
    """RMS per image (calibrated and nominal reference, log) and the calibrated residuals'
    histogram; ``what`` says which images (e.g. "calibration images", "held-out images")."""
    imgs = ev.images
    x = np.arange(len(imgs))
    fig = new_figure(9, 6.5)
    a1, a2 = fig.subplots(2, 1)
    nominal = [r["nominal_px"] for r in imgs]
    a1.plot(x, nominal, "s", color="0.55", ms=4,
            label=f"nominal reference ({ev.rms['nominal']:.3f} px RMS)")  # fmt: skip
    a1.plot(x, [r["calibrated_px"] for r in imgs], "o", color="tab:red", ms=4,
            label=f"calibrated ({ev.rms['calibrated']:.3f} px RMS)\npredicted from the joints, "
                  "not the fit's RMS")  # fmt: skip
    log_y(a1)
    a1.set_xlabel(f"image ({what}, in frame order)")
    a1.set_ylabel("reprojection RMS (px, log)")
    a1.set_title("(a) every image predicted from its joint reading, per image", y=1.0)
    a1.grid(alpha=0.3, which="both")
    legend_outside(a1)
    e = ev.residuals.get("calibrated", np.zeros((0, 2)))
    within = within_image(e, [int(r.get("features", 0)) for r in imgs])
    lim = float(np.percentile(np.abs(e), 99.5)) * 1.2 if len(e) else 1.0
    bins = np.linspace(-lim, lim, 41)
    for j, (lab, c) in enumerate((("u", "tab:blue"), ("v", "tab:orange"))):
        if len(e):
            sd = float(np.std(e[:, j]))
            a2.hist(np.clip(e[:, j], -lim, lim), bins=bins, histtype="step", lw=1.5, color=c,
                    label=f"{lab} (std {sd:.3f} px)")  # fmt: skip
        if within is not None and len(e):
            a2.hist(np.clip(within[:, j], -lim, lim), bins=bins, histtype="stepfilled",
                    alpha=0.25, color=c, label=f"{lab} less its image's shift "
                    f"(std {float(np.std(within[:, j])):.3f} px)")  # fmt: skip
    a2.set_xlabel("calibrated model: predicted - detected (px; clipped at the plot edges)")
    a2.set_ylabel("features")
    note = "" if within is None else " (filled: less each image's shift, its joint reading's)"
    a2.set_title(f"(b) residuals of the {len(e)} features{note}", y=1.0)
    a2.grid(alpha=0.3)
    legend_outside(a2)
    stack_layout(fig)
    return fig


def parameter_figure(rows: list[dict]) -> Any:
    """``|estimate - truth|`` beside its 1-sigma (when any is known) and ``|nominal - truth|``
    per minimal parameter (log scale); rows as :func:`selfcal.kinematics.accuracy.parameter_table` (mm / deg,
    with truth)."""
    groups = [(u, [r for r in rows if r["unit"] == u]) for u in ("mm", "deg")]
    groups = [(u, g) for u, g in groups if g]
    fig = new_figure(9, 3.4 * len(groups))
    axs = fig.subplots(len(groups), 1, squeeze=False)
    tiny = 1e-12  # an exact zero has no place on a log axis
    for ax, (unit, g) in zip(axs[:, 0], groups):
        x = np.arange(len(g))
        nom = [max(abs(r["nominal"] - r["truth"]), tiny) for r in g]
        est = [max(abs(r["estimate"] - r["truth"]), tiny) for r in g]
        sd = [np.nan if r["std"] is None else r["std"] for r in g]
        ax.plot(x, nom, "s", color="0.55", ms=5, label="|nominal - truth|")
        ax.plot(x, est, "o", color="tab:red", ms=5, label="|estimate - truth|")
        if np.isfinite(sd).any():  # a board run has no sigmas: no legend entry without marks
            ax.plot(x, sd, "_", color="k", ms=12, mew=1.5, label="1 sigma (from the fit)")
        ax.set_xticks(x, [r["name"] for r in g], rotation=90, fontsize=8)
        ax.set_xlabel("minimal MCPC parameter (in the estimate's frame)")
        ax.set_ylabel(f"|error| ({unit}, log)")
        log_y(ax)
        ax.set_title(f"parameters in {unit}: estimate and nominal against the truth", y=1.0)
        ax.grid(alpha=0.3, which="both")
        legend_outside(ax)
    # the names stand rotated below each axes, as high as the longest (8 pt: 0.075 in a letter)
    names = [0.075 * max(len(r["name"]) for r in g) for _, g in groups]
    stack_layout(fig, bottom=0.45 + names[-1], gap=0.7 + max(names[:-1], default=0.0))
    return fig


def write_figure(fig: Any, root: str | Path, name: str) -> Path:
    """Save ``fig`` as ``root/figures/name`` and close it; returns the path."""
    path = Path(root) / FIGURES / name
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path)
    close_figure(fig)
    return path


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.asarray(v) ** 2)))
