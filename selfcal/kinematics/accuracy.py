"""Accuracy report: calibrated and nominal models against ground truth.

The tool tip is the point of the paper's Table II (the origin of the last DH frame); the camera and
the tip are one rigid assembly with a known internal transform ``T_cam_tip``, so a model whose
tool is the left camera predicts the tip as ``T_world_cam(q) T_cam_tip``.

Tool-tip errors are measured after the best rigid alignment (rotation and translation, no scale)
of the predicted positions to the true ones over the validation postures: the placement of the
robot relative to the scene (the world frame) is not observable by a camera looking at an unknown
scene, and it does not count.
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, minimal_indices, param_is_angle, param_names
from selfcal.transforms import kabsch

__all__ = ["tool_tips", "aligned_errors", "parameter_table", "wrap_deg", "format_table_iv"]


def tool_tips(model_cam: MCPCModel, q: np.ndarray, T_cam_tip: np.ndarray) -> np.ndarray:
    """Tool-tip positions (m, 3) in the model's world frame, for joints ``q`` (m, n) rad."""
    return (fk_tool(model_cam, q) @ np.asarray(T_cam_tip, dtype=float)[:, 3])[:, :3]


def aligned_errors(pred_m: np.ndarray, true_m: np.ndarray) -> dict:
    """Errors of predicted points after their best rigid alignment onto the true ones.

    Returns ``{"rms", "max"}`` in mm, the per-point error vectors (mm, in the true frame) and the
    alignment ``T_true_pred``.
    """
    T = kabsch(pred_m, true_m)
    aligned = pred_m @ T[:3, :3].T + T[:3, 3]
    e = (aligned - true_m) * 1000.0
    n = np.linalg.norm(e, axis=1)
    return {
        "rms": float(np.sqrt(np.mean(n**2))),
        "max": float(n.max()),
        "errors_mm": e,
        "T_true_pred": T,
    }


def parameter_table(
    est: MCPCModel, std_by_name: dict[str, float], truth: MCPCModel | None, nominal: MCPCModel
) -> list[dict]:
    """Rows ``{name, unit, estimate, std, truth, nominal}`` over the minimal set (mm / deg).

    ``truth`` and ``nominal`` must already be expressed in the estimate's world frame and offsets.
    An angle's estimate and truth are shown in the nominal's branch (nominal plus the difference
    wrapped to (-180, 180]): -179.98 against 180.01 is a difference of 0.01 deg, not 359.99.
    A link whose three angles are all estimated (the tool's) is shown in the nominal's Euler
    branch as well: ``Rx(a) Ry(b) Rz(c) = Rx(a + 180) Ry(180 - b) Rz(c + 180)``, so alpha5 -90.10
    and gamma5 179.83 against the nominal's 90.07 and -0.78 are the same rotation, 0.1 and 0.6
    deg apart, not two 180-degree errors.
    """
    idx = minimal_indices(est.joint_types)
    ang = param_is_angle(idx)
    full = [i for i in range(est.n + 1) if {6 * i, 6 * i + 1, 6 * i + 2} <= set(idx.tolist())]
    est = euler_branch_like(est, nominal, full)
    truth = None if truth is None else euler_branch_like(truth, nominal, full)
    rows = []
    for name, k, a in zip(param_names(idx), idx, ang):
        s = 180.0 / np.pi if a else 1000.0

        def val(m: MCPCModel | None, k: int = k, s: float = s, a: bool = a) -> float | None:
            if m is None:
                return None
            v = float(m.params.reshape(-1)[k] * s)
            if not a or m is nominal:
                return v
            ref = float(nominal.params.reshape(-1)[k] * s)
            return ref + wrap_deg(v - ref)

        std = std_by_name.get(name)
        rows.append(
            {
                "name": name,
                "unit": "deg" if a else "mm",
                "estimate": val(est),
                "std": None if std is None or not np.isfinite(std) else float(std * s),
                "truth": val(truth),
                "nominal": val(nominal),
            }
        )
    return rows


def euler_branch_like(m: MCPCModel, like: MCPCModel, links: list[int]) -> MCPCModel:
    """``m`` with the angles of each link in ``links`` written as the Euler triple of the same
    rotation (``(a, b, c)`` or ``(a + pi, pi - b, c + pi)``, rad) nearer ``like``'s, each angle
    difference wrapped to (-pi, pi]; every shape matrix unchanged."""
    p = m.params.copy()
    for i in links:
        a, b, c = p[i, :3]
        dual = np.array([a + np.pi, np.pi - b, c + np.pi])
        d0 = np.abs((p[i, :3] - like.params[i, :3] + np.pi) % (2 * np.pi) - np.pi).max()
        d1 = np.abs((dual - like.params[i, :3] + np.pi) % (2 * np.pi) - np.pi).max()
        if d1 < d0:
            p[i, :3] = (dual + np.pi) % (2 * np.pi) - np.pi
    return m.with_params(p)


def wrap_deg(d: float) -> float:
    """An angle difference (deg) wrapped to (-180, 180]."""
    return float(d - 360.0 * np.ceil((d - 180.0) / 360.0))


def format_table_iv(rows: list[dict]) -> str:
    """A Markdown table like the paper's Table IV (desired, true, predicted, errors; mm)."""
    head = (
        "| pos | axis | desired (nominal model) | true (simulator) | calibrated model | "
        "error nominal (true - desired) | error calibrated (true - calibrated) |\n"
        "|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for r in rows:
        for k, ax in enumerate("xyz"):
            lines.append(
                f"| {r['position']} | p_{ax} | {r['desired_mm'][k]:.2f} | {r['true_mm'][k]:.2f} | "
                f"{r['calibrated_mm'][k]:.2f} | {r['true_mm'][k] - r['desired_mm'][k]:+.2f} | "
                f"{r['true_mm'][k] - r['calibrated_mm'][k]:+.2f} |"
            )
    return head + "\n".join(lines) + "\n"
