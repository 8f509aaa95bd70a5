"""The studies of ``selfcal study``: each a named sweep of run settings (``STUDIES``).

A ``Study``'s phases yield the settings of its runs for a budget (``quick`` or ``full``); a later
phase may depend on the rows of an earlier one (``observation``: each analytic run takes the
effective corner noise of its paired rendered run). ``BASE`` holds the settings a sweep leaves
alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = ["BASE", "Study", "STUDIES"]

BASE = {
    "render": False,
    "pixel_sigma": 0.25,
    "image_sigma": 2.0,
    "poses": 30,
    "perturb_scale": 1.0,
}


@dataclass(frozen=True)
class Study:
    """A named sweep: ``phases(budget, done_rows, first_seed)`` yields the settings of each phase
    in turn (each setting with the seeds ``first_seed``, ``first_seed + 1``, ...)."""

    name: str
    x: str
    xlabel: str
    phases: tuple[Callable[[str, list[dict], int], list[dict]], ...]
    log_x: bool = False
    series: str | None = None  # a settings key that splits the runs into curves


def _seeds(budget: str, quick: int, full: int, first: int) -> range:
    return range(first, first + (quick if budget == "quick" else full))


def _grid(
    budget: str, key: str, quick: list, full: list, seeds: tuple[int, int], first: int, **fixed
):
    vals = quick if budget == "quick" else full
    return [
        {**BASE, **fixed, key: v, "seed": s} for v in vals for s in _seeds(budget, *seeds, first)
    ]


def _noise(budget, _rows, first):
    return _grid(
        budget,
        "pixel_sigma",
        [0.0, 0.5, 2.0],
        [0.0, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0],
        (2, 8),
        first,
        poses=12 if budget == "quick" else 30,
    )


def _poses(budget, _rows, first):
    return _grid(budget, "poses", [8, 40], [6, 8, 12, 20, 30, 50, 70, 100], (3, 8), first)


def _perturbation(budget, _rows, first):
    return _grid(
        budget,
        "perturb_scale",
        [0.5, 2.0],
        [0.25, 0.5, 1.0, 2.0, 4.0, 8.0],
        (2, 8),
        first,
        poses=12 if budget == "quick" else 30,
    )


def _observation_rendered(budget, _rows, first):
    return _grid(
        budget,
        "image_sigma",
        [2.0],
        [0.0, 2.0, 8.0],
        (2, 5),
        first,
        render=True,
        poses=8 if budget == "quick" else 20,
        pixel_sigma=0.0,
    )


def _observation_analytic(budget, rows, first):
    from selfcal.studies.runs import settings_key

    out = []
    for st in _observation_rendered(budget, rows, first):
        match = [r for r in rows if r["key"] == settings_key(st) and r["status"] == "ok"]
        if match:
            eff = round(float(match[0]["eff_noise_px"]), 4)
            # image_sigma records the rendered run it is paired with (unused when not rendering).
            out.append({**st, "render": False, "pixel_sigma": eff})
    return out


STUDIES: dict[str, Study] = {
    "noise": Study("noise", "pixel_sigma", "analytic corner noise sigma (px)", (_noise,)),
    "poses": Study("poses", "poses", "calibration poses", (_poses,), log_x=True),
    "perturbation": Study(
        "perturbation",
        "perturb_scale",
        "injected error size (x 1 mm, x 0.5 deg per parameter)",
        (_perturbation,),
        log_x=True,
    ),
    "observation": Study(
        "observation",
        "image_sigma",
        "rendered image noise sigma (grey levels)",
        (_observation_rendered, _observation_analytic),
        series="render",
    ),
}
