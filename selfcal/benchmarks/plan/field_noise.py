"""The rendered field benchmark's corner noise, measured apart from the draws it judges (issue
#30; :mod:`selfcal.benchmarks.plan.field_compare` ``--render``).

The plan and its first forecast are made for the corner noise a user states (``--pixel-sigma``).
A rendered image's noise is what the renderer and the detector make of it, a property of the
cell one can measure: the set's postures rendered once more for a draw the table does not hold
(:data:`NOISE_SEED`: its own arm and image noise), every detected corner against the true
corner's projection (:func:`selfcal.benchmarks.corner_noise.field_corner_noise`), the corners
beyond the field route's outlier floor left out; with the marker centres' noise
(:attr:`~selfcal.benchmarks.corner_noise.CornerNoise.centre_sigma_px`), the part of a rendered
marker's corner errors the field route's tool point feels (issue #30). The forecast at that noise then predicts the
draws without having seen them (never fitted to the outcome). The measurement is kept with the
cell, the seed and the code that made it (:func:`selfcal.benchmarks.doc_blocks.code_version`),
as the draws' journal is, and made again when any of them is not this run's.
"""

from __future__ import annotations

import json
from pathlib import Path

from selfcal.benchmarks.doc_blocks import code_version
from selfcal.io.atomic import write_text_atomic

__all__ = ["NOISE_SEED", "measured_noise"]

NOISE_SEED = 0
"""The draw whose images measure the corner noise: the arm and noise seed 0, where the table's
draws are seeds 1 - N."""


def measured_noise(
    root: Path, config: Path, joints_deg: list, cell: str, pixel_sigma_px: float
) -> dict:
    """The corner noise (:meth:`selfcal.benchmarks.corner_noise.CornerNoise.to_json`, px) of
    the postures ``joints_deg`` (deg) of the replay scenario ``config`` rendered for the draw
    :data:`NOISE_SEED` as the table's draws are (``pixel_sigma_px`` their setting), with ``cell``
    (the set's :func:`~selfcal.benchmarks.plan.field_compare.cell_stamp`), the seed and the
    ``code`` that measured it (:func:`code_version`); kept in ``root/corner-noise.json`` and read
    from it again only when it was measured for the same ``cell`` and seed by the same code, else
    measured again and the file replaced (the images are not kept)."""
    import tempfile

    from selfcal.benchmarks.corner_noise import field_corner_noise
    from selfcal.studies.montecarlo.run import acquire_draw

    path = root / "corner-noise.json"
    code = code_version()
    if path.exists():
        got = json.loads(path.read_text())
        if (got.get("cell"), got.get("seed"), got.get("code", "")) == (cell, NOISE_SEED, code):
            return got
        print(f"{path}: measured for another cell, seed or code (the code at "
              f"{got.get('code') or 'not recorded'}; this run's {code}): measured again",
              flush=True)  # fmt: skip
    settings = {"config": str(config), "poses": len(joints_deg), "pixel_sigma": pixel_sigma_px,
                "seed": NOISE_SEED, "traj_seed": 1, "perturb_seed": NOISE_SEED, "dither": True,
                "joints_deg": joints_deg, "render": True}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="selfcal-noise-") as d:
        acquire_draw(settings, Path(d) / "run")
        noise = field_corner_noise(Path(d) / "run")
    out = {"cell": cell, "seed": NOISE_SEED, "code": code, **noise.to_json()}
    write_text_atomic(path, json.dumps(out, indent=1) + "\n")
    return out
