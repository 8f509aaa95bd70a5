"""The eye-to-hand simulator takes the scenario's explicit errors ([perturbation.table]) as the
eye-in-hand one does: a new user's changed copy of a plan's scenario (beta2 = 0.1 deg added)
acquired the very same detections as the unchanged one, and `selfcal check` said "unchanged"
(the static cell drew its own perturbed chain and dropped the table)."""

from __future__ import annotations

import numpy as np

from selfcal.acquisition.simulator_setup import sim_setup
from selfcal.config.scenario import load_scenario, scenarios_dir
from selfcal.sim.actual import param_index


def _cell(table: dict) -> np.ndarray:
    s = load_scenario(scenarios_dir() / "eye-to-hand.toml",
                      {"noise": {"render": False}, "perturbation": {"table": table}})  # fmt: skip
    static = sim_setup(s).static
    assert static is not None
    return static.actual.params.reshape(-1)


def test_the_table_moves_the_static_cells_chain():
    base, changed = _cell({}), _cell({"beta2": 0.1, "lx1": 0.5})
    n = len(base) // 6 - 1
    d = changed - base
    expect = np.zeros_like(d)
    expect[param_index("beta2", n)] = np.radians(0.1)
    expect[param_index("lx1", n)] = 0.5e-3
    np.testing.assert_allclose(d, expect, atol=1e-15)
