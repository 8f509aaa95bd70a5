"""The words of a simulated board run's report: ``report.md`` from the report's numbers
(:func:`board_report_markdown`; the numbers: :func:`selfcal.pipeline.board_run.board_truth_report`)."""

from __future__ import annotations

from selfcal.pipeline.board_truth_accuracy import predicted_point_markdown
from selfcal.pipeline.report_fit import bound_markdown, figure_links, parameter_markdown

__all__ = ["board_report_markdown"]


def _num(x: float | None, fmt: str) -> str:
    return "" if x is None else format(x, fmt)


def _camera_markdown(rows: dict) -> list[str]:
    return [
        "| parameter | estimate | truth | std | z | Cramer-Rao bound |",
        "|---|---|---|---|---|---|",
        *(
            f"| {n} | {c['estimate']:.6g} | {c['truth']:.6g} | {_num(c['std'], '.3g')} | "
            f"{_num(c['z'], '+.2f')} | {_num(c.get('bound'), '.3g')} |"
            for n, c in rows.items()
        ),
    ]


def board_report_markdown(r: dict) -> str:
    """``report.md`` of a simulated board run from its ``report.json`` content ``r``
    (:func:`selfcal.pipeline.board_run.board_truth_report`): tool tip and camera pose against
    the truth, the hand-eye, every camera parameter and the kinematic parameters (mm, deg,
    px)."""
    v = r["validation"]
    t = v["tool_tip_error_mm"]
    cp = v["camera_pose_in_board"]
    he = r["hand_eye"]
    cam = _camera_markdown(r["camera"])
    for name, k in r["rig"].items():
        e = k["extrinsics"]
        cam += [
            "",
            f"Camera {name}: pose in the first camera's frame "
            f"{e['position_mm']['rms']:.3f} mm / {e['rotation_deg']['rms']:.4f} deg from the truth.",
            "",
            *_camera_markdown(k["camera"]),
        ]
    return "\n".join(
        [
            f"# Calibration report ({r['target']['type']} board)",
            "",
            f"Validation postures: {v['poses']} (never used to calibrate).",
            "",
            "| model | tool-tip RMS (mm) | max (mm) | camera pose in the board: position RMS (mm)"
            " | rotation RMS (deg) |",
            "|---|---|---|---|---|",
            *(
                f"| {k} | {t[k]['rms']:.3f} | {t[k]['max']:.3f} | "
                f"{cp[k]['position_mm']['rms']:.3f} | {cp[k]['rotation_deg']['rms']:.4f} |"
                for k in ("nominal", "calibrated")
            ),
            "",
            bound_markdown(v.get("tool_tip_bound_mm"), t["calibrated"]["rms"]),
            *predicted_point_markdown(v.get("predicted_point")),
            "",
            f"Hand-eye (last link -> camera) against the truth: calibrated "
            f"{he['calibrated']['position_mm']['rms']:.3f} mm / "
            f"{he['calibrated']['rotation_deg']['rms']:.4f} deg, nominal "
            f"{he['nominal']['position_mm']['rms']:.3f} mm / "
            f"{he['nominal']['rotation_deg']['rms']:.4f} deg. Reprojection RMS "
            f"{r['reprojection_rms_px']:.3f} px over {r['frames']['used']}/"
            f"{r['frames']['planned']} frames.",
            "",
            "## Camera",
            "",
            *cam,
            "",
            "## Kinematic parameters",
            "",
            parameter_markdown(r["parameters"], truth=True),
            "",
            r["parameters_note"] + ".",
            *figure_links(r.get("figures", [])),
            "",
        ]
    )
