"""``python -m selfcal.benchmarks.plan.field_hidden [--robot kr6-r900] [--seeds 1,2,3,4]``: how
far off the detector returns a field's markers that a raised support partly hides, on rendered
views of the field benchmark's posture sets (docs/plan.md, "A marker field"; issue #30).

The sets of :mod:`selfcal.benchmarks.plan.field_compare`'s cell (``--robot``'s arm, 0.1 px):
the plan of 12 as ``selfcal plan`` makes it by default, the plan of 12 with clear views
(:attr:`selfcal.calibration.field.plan.FieldPlanSetup.clear_views`, the rendered table's) and
the random 30, each rendered for every seed of ``--seeds`` (its arm and image noise, as the
table's draws are) and detected by the field route. Every detected marker's corners
against the true corner's projection at the frame's true camera pose, the markers grouped by
where a support hides their tile at that pose (lines of sight to a 33 x 33 grid over the tile,
:meth:`selfcal.calibration.field.plan_sight.Supports.hidden_points`): clear; hidden only in
the outer half of the quiet zone, its second quarter or its first (the points on the square's
edge are the square's); the black square crossed. Per group: the markers, their worst corner's
median and 90th percentile, and the corners 0.1 - 1 px off (above about 5 times the rendered
noise, kept by the field route's 1 px outlier floor) and above 1 px (dropped by it). Renders
only: no calibration. Units: px.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["GROUPS", "main", "marker_errors"]

GRID = 33
"""Lines of sight per side of a tile's grid (a quarter module apart on a tile of 8 modules:
the example's 6-module markers in a quiet zone of one)."""
GROUPS = ("clear", "outer half of the quiet zone", "its second quarter", "its first quarter",
          "the square crossed")  # fmt: skip
"""The groups of detected markers, by the hidden point nearest the black square."""


def _group(hidden: np.ndarray, reach: np.ndarray) -> int:
    """The group (index in :data:`GROUPS`) of a marker whose grid points ``hidden`` (p,) bool
    lie ``reach`` (p,) out from the black square (its share of the quiet zone; <= 0 inside)."""
    if not hidden.any():
        return 0
    near = reach[hidden].min()
    return 4 if near <= 0 else 3 if near <= 0.25 else 2 if near <= 0.5 else 1


def marker_errors(root: Path) -> list[tuple[int, np.ndarray]]:
    """``(group, its four corners' errors (4,) px)`` of every marker the field route detects in the
    rendered field dataset ``root`` (its first camera), the group as :func:`_group` at the
    frame's true camera pose."""
    from selfcal.calibration.field.detections import detect_dataset
    from selfcal.calibration.field.plan_sight import Supports
    from selfcal.errors import InternalError
    from selfcal.io.dataset import Dataset
    from selfcal.io.truth import read_truth
    from selfcal.sim.markers import MarkerField
    from selfcal.transforms import inv_pose

    ds = Dataset.open(root)
    truth = read_truth(root / "truth.json")
    if truth.marker_field is None:
        raise InternalError(f"{root}: the truth has no marker field (not a field scenario)")
    field = MarkerField.from_dict(truth.marker_field)
    sup = Supports(*field.support_boxes(), tile_ratio=field.tile_size_m / field.size_m)
    corners = field.corners_world()
    tiles = sup.tiles(corners)
    a = np.linspace(0.0, 1.0, GRID)
    u, v = (g.ravel()[None, :, None] for g in np.meshgrid(a, a, indexing="ij"))
    top = tiles[:, None, 0] + u * (tiles[:, None, 1] - tiles[:, None, 0])
    grid = top + v * (tiles[:, None, 3] + u * (tiles[:, None, 2] - tiles[:, None, 3]) - top)
    half = np.maximum(np.abs(u.ravel() - 0.5), np.abs(v.ravel() - 0.5)) * 2 * sup.tile_ratio
    # 0 at the square's edge, 1 at the tile's; rounded: the grid's points fall on the groups' edges
    reach = np.round((half - 1.0) / (sup.tile_ratio - 1.0), 9)
    row = {int(m): k for k, m in enumerate(field.ids)}
    out = []
    for (index, name), found in detect_dataset(ds).detections.items():
        fr = truth.frame(int(index))
        if name != ds.info.cameras[0] or fr is None or not found:
            continue
        hidden = sup.hidden_points(fr.T_world_cam_left[None, :3, 3], grid)[0]
        T = inv_pose(fr.T_world_cam_left)
        for mid, uv in found.items():
            k = row[int(mid)]
            X = corners[k] @ T[:3, :3].T + T[:3, 3]
            d = np.asarray(uv, dtype=float).reshape(4, 2) - truth.intrinsics_left.project(X)
            out.append((_group(hidden[k], reach), np.linalg.norm(d, axis=1)))
    return out


def main(argv: list[str] | None = None) -> int:
    """Render, detect and print the table (module docstring)."""
    from selfcal.benchmarks.plan.field_compare import field_sets
    from selfcal.studies.montecarlo.run import acquire_draw

    ap = benchmark_parser(__file__, description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--robot", default="kr6-r900", help="the arm (default kr6-r900)")
    ap.add_argument("--seeds", default="1,2,3,4", help="the draws rendered (comma-separated)")
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    rows: dict[str, list[tuple[int, np.ndarray]]] = {}
    with tempfile.TemporaryDirectory(prefix="selfcal-hidden-") as d:
        sets = {"plan 12 (default)": field_sets(Path(d) / "default", robot_name=a.robot,
                                               pixel_sigma_px=0.1)["plan 12"]}  # fmt: skip
        clear = field_sets(Path(d) / "clear", robot_name=a.robot, pixel_sigma_px=0.1, render=True)
        sets |= {"plan 12 (clear views)": clear["plan 12"], "random 30": clear["random 30"]}
        for name, (path, q, _) in sets.items():
            for s in seeds:
                run = Path(d) / f"{name.split()[-1].strip('()')}-{s}"
                acquire_draw({"config": str(path), "poses": len(q), "pixel_sigma": 0.1,
                              "seed": s, "traj_seed": 1, "perturb_seed": s, "dither": True,
                              "joints_deg": q.tolist(), "render": True}, run)  # fmt: skip
                rows.setdefault(name, []).extend(marker_errors(run))
    print("| postures | markers by where a support hides them | detected | worst corner, median "
          "(px) | 90th percentile | corners 0.1 - 1 px off (the floor keeps them) | corners "
          "above 1 px |\n|---|---|---|---|---|---|---|")  # fmt: skip
    for name, got in rows.items():
        g, e = np.array([r[0] for r in got]), np.array([r[1] for r in got])
        for k, words in enumerate(GROUPS):
            x = e[g == k]
            if len(x):
                w = x.max(axis=1)
                print(f"| {name} | {words} | {len(x)} | {np.median(w):.3f} | "
                      f"{np.percentile(w, 90):.3f} | {int(np.sum((x > 0.1) & (x <= 1.0)))} | "
                      f"{int(np.sum(x > 1.0))} |")  # fmt: skip
    print(f"\n`uv run python -m selfcal.benchmarks.plan.field_hidden --robot {a.robot} --seeds "
          f"{a.seeds}`")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
