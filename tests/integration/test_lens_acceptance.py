"""Acceptance of real lenses (#12, section 7, camera items) on the stereo rig + ArUco field with
scenarios/lens.toml (k1 = -0.25, k2 = 0.1, p1 = 1e-3, p2 = -5e-4, principal point (+12, -8) px
from the centre; fx, mu, cx, cy, k1, k2, p1, p2 free, started from the centred distortion-free
pinhole).

- every free camera parameter within 3 sigma of truth (sigma: the calibration's covariance),
  analytic and rendered (measured |z| <= 1.7 analytic, <= 1.98 rendered (k1); the rendered
  corners are re-detected through the estimated lens, selfcal.camera.undistort);
- one camera (self-calibration without a rig, synthetic field): the same, max |z| 1.9;
- the calibrated tool tip within 1.3x the Cramer-Rao bound over 30 Monte Carlo draws on the
  analytic path (selfcal/studies/montecarlo/run.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mc_draws import draw_without_fair_nominal

from selfcal.config.scenario import load_scenario
from selfcal.pipeline.run import run_acquire, run_calibrate, run_report

LENS_TOML = Path(__file__).resolve().parents[2] / "scenarios" / "lens.toml"
MONO_TOML = LENS_TOML.with_name("mono.toml")
MONO_CHARUCO_TOML = LENS_TOML.with_name("mono-charuco.toml")


def _z_scores(tmp_path: Path, render: bool, config: Path = LENS_TOML) -> dict[str, float]:
    s = load_scenario(config, overrides={"noise": {"render": render}})
    run_acquire(s, tmp_path, quiet=True)
    result = run_calibrate(tmp_path, quiet=True)
    report = run_report(tmp_path, quiet=True)
    free = set(s.camera.free)  # and fy = mu fx, by OpenCV's name
    assert result.intrinsics.model == "opencv" and set(result.intrinsics.std) == free | {"fy"}
    rows = report["intrinsics"]
    return {
        n: (rows[n]["estimate"] - rows[n]["truth"]) / result.intrinsics.std[n]
        for n in s.camera.free
    }


@pytest.mark.slow
@pytest.mark.parametrize("render", [False, True], ids=["analytic", "rendered"])
def test_every_free_camera_parameter_within_3_sigma(tmp_path, render):
    z = _z_scores(tmp_path, render)
    print(
        f"\nz-scores ({'rendered' if render else 'analytic'}):",
        {k: round(v, 2) for k, v in z.items()},
    )
    assert all(abs(v) < 3.0 for v in z.values()), z


@pytest.mark.slow
@pytest.mark.parametrize("render", [False, True], ids=["analytic", "rendered"])
def test_mono_scenario_every_free_camera_parameter_within_3_sigma(tmp_path, render):
    """scenarios/mono.toml: the left camera alone through the whole pipeline (acquire, the
    self-calibration from views of different configurations, the joint refinement, the report).
    Measured |z| <= 2.0 analytic (p1), <= 1.17 rendered (k2; every frame registered)."""
    z = _z_scores(tmp_path, render, MONO_TOML)
    print(f"\nmono z-scores ({'rendered' if render else 'analytic'}):",
          {k: round(v, 2) for k, v in z.items()})  # fmt: skip
    assert all(abs(v) < 3.0 for v in z.values()), z


@pytest.mark.slow
def test_monte_carlo_tool_tip_within_1_3x_the_bound_with_a_lens():
    from selfcal.studies.montecarlo.run import run_montecarlo

    rows, summary = run_montecarlo(
        30, None, jobs=2, quiet=True, config=LENS_TOML, task=draw_without_fair_nominal
    )
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) == 30, [r["status"] for r in rows if r["status"] != "ok"]
    ratio = summary["joint"]["tool_tip_ratio"]
    print(f"\nlens Monte Carlo: joint tool-tip ratio {ratio:.3f}")
    assert ratio <= 1.3
    for name in ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"):  # errors match the bounds
        z = np.array([r[f"joint_cam_err_{name}"] / r[f"bound_cam_{name}"] for r in ok])
        assert np.sqrt(np.mean(z**2)) < 1.5, (name, z.round(2))


@pytest.mark.slow
def test_mono_self_calibration_frees_the_lens():
    """One camera (the left of a synthetic stereo scene, 30 views, 0.5 px noise) and the marker
    field: the self-calibration without a rig recovers every free parameter within 3 sigma
    (measured over seeds 0-4: max |z| 1.93)."""
    from selfcal.calibration.field.self_calibration import self_calibrate
    from selfcal.calibration.field.synthetic import synthetic_stereo_scene
    from selfcal.camera import camera_model
    from selfcal.estimation.observations import Observations

    free = ["fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"]
    lens = {"k1": -0.25, "k2": 0.1, "p1": 1e-3, "p2": -5e-4}
    truth = camera_model("opencv", fx=800.0, mu=1.0, cx=331.5, cy=231.5, width=640, height=480,
                         coeffs=lens, free=free)  # fmt: skip
    start = camera_model("opencv", fx=1.0, mu=1.0, cx=319.5, cy=239.5, width=640, height=480,
                         free=free)  # fmt: skip
    sc = synthetic_stereo_scene(30, seed=1, noise_px=0.5, camera=truth)
    left = {(i, 0): m for (i, c), m in sc.detections.items() if c in (0, "left")}
    obs = Observations.from_corners(left, n_configs=30, cameras=("left",))
    res = self_calibrate(obs, 640, 480, scale_markers=sc.scale_markers,
                         scale_distance_m=sc.scale_distance_m, camera=start, rig=False)  # fmt: skip
    z = (res.camera.free_values() - truth.free_values()) / np.sqrt(np.diag(res.cov_fx_mu))
    print("\nmono z-scores:", dict(zip(free, z.round(2))))
    assert np.all(np.abs(z) < 3.0)


def _acceptance_monte_carlo(config: Path, label: str) -> None:
    """30 analytic draws of ``config`` (the issue's acceptance): the joint tool tip within
    1.3x the bound and every free camera parameter's error RMS / bound below 1.5 (an efficient
    estimator's 95 % range over 30 draws is 0.75 .. 1.25)."""
    from selfcal.studies.montecarlo.run import run_montecarlo

    rows, s = run_montecarlo(
        30, None, jobs=2, quiet=True, config=config, task=draw_without_fair_nominal
    )
    assert all(r["status"] == "ok" for r in rows), [r["status"] for r in rows]
    ratio = s["joint"]["tool_tip_ratio"]
    print(f"\n{label} Monte Carlo (30 draws): joint tool-tip ratio {ratio:.3f}, cameras",
          {k: round(v, 2) for k, v in s["camera_ratios"].items()})  # fmt: skip
    assert ratio <= 1.3
    assert set(s["camera_ratios"]) == set(load_scenario(config).camera.free) | {"fy"}
    assert all(v < 1.5 for v in s["camera_ratios"].values()), s["camera_ratios"]


@pytest.mark.slow
def test_mono_monte_carlo_tool_tip_within_1_3x_the_bound():
    """scenarios/mono.toml (one camera + the field; the table in docs/cameras.md): measured
    1.115, camera ratios 0.85 .. 0.99."""
    _acceptance_monte_carlo(MONO_TOML, "mono")


@pytest.mark.slow
def test_mono_charuco_monte_carlo_tool_tip_within_1_3x_the_bound():
    """scenarios/mono-charuco.toml (one camera + ChArUco, the scenario's own board and camera)
    through ``selfcal montecarlo``'s draws on the analytic path against the board route's
    Cramer-Rao bound (:mod:`selfcal.studies.montecarlo.board`; the table in docs/cameras.md):
    measured 0.901, camera ratios 0.74 .. 1.11."""
    _acceptance_monte_carlo(MONO_CHARUCO_TOML, "ChArUco")
