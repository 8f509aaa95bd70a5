"""The report's camera rows against the truth: every free parameter of every camera.

A rig whose cameras have their own intrinsics (``calibration.json`` ``cameras``, #12) reports
each camera's estimate against its own true model (``truth.json`` ``cameras.left`` /
``cameras.right``) with the z-score ``(estimate - truth) / std``; a shared camera is reported
by the report's ``intrinsics`` rows (:func:`camera_rows`) as before.
"""

from __future__ import annotations

from selfcal.camera import CameraModel
from selfcal.io.calibration import CalibrationResult
from selfcal.io.truth import Truth

__all__ = ["camera_rows", "rig_camera_rows", "rig_camera_markdown"]


def camera_rows(est: CameraModel, std: dict[str, float], truth: CameraModel) -> dict:
    """Every free camera parameter but fx, mu: ``{name: {estimate, truth, std}}`` (truth of a
    parameter the true model does not have: 0, no lens term)."""
    true = dict(zip(truth.names, truth.values().tolist()))
    vals = dict(zip(est.names, est.values().tolist()))
    return {
        n: {"estimate": vals[n], "truth": true.get(n, 0.0), "std": std.get(n)}
        for n in est.free
        if n not in ("fx", "mu")
    }


def rig_camera_rows(cal: CalibrationResult, truth: Truth | None) -> dict[str, dict]:
    """``{camera: {parameter: {estimate, std[, truth, z]}}}`` of every free parameter of every
    camera with its own intrinsics (px or unitless; with ``truth`` each against its own true
    camera, ``z`` None without a std); empty for a shared camera."""
    trues = {} if truth is None else {"left": truth.intrinsics_left,
                                      "right": truth.intrinsics_right}  # fmt: skip
    out: dict[str, dict] = {}
    for rc in cal.cameras:
        est = rc.intrinsics.camera()
        std = rc.intrinsics.std
        vals = dict(zip(est.names, est.values().tolist()))
        rows = {n: {"estimate": vals[n], "std": std.get(n)} for n in est.free}
        if rc.name in trues:
            true = dict(zip(trues[rc.name].names, trues[rc.name].values().tolist()))
            for n, r in rows.items():
                t, s = true.get(n, 0.0), r["std"]
                r |= {"truth": t, "z": (r["estimate"] - t) / s if s else None}
        out[rc.name] = rows
    return out


def rig_camera_markdown(rows: dict[str, dict]) -> list[str]:
    """The Markdown table of :func:`rig_camera_rows` (no lines when empty)."""
    if not rows:
        return []
    truth = all("truth" in r for params in rows.values() for r in params.values())
    head = "| camera | parameter | estimate | std |" + (" truth | z |" if truth else "")
    lines = ["## Cameras (each its own intrinsics)", "", head,
             "|---|---|---|---|" + ("---|---|" if truth else "")]  # fmt: skip
    for cam, params in rows.items():
        for n, r in params.items():
            std = "" if r["std"] is None else f"{r['std']:.3g}"
            line = f"| {cam} | {n} | {r['estimate']:.6g} | {std} |"
            if truth:
                z = "" if r["z"] is None else f"{r['z']:+.2f}"
                line += f" {r['truth']:.6g} | {z} |"
            lines.append(line)
    return [*lines, ""]
