"""A drift check's p-value as the verdict line prints it."""

from __future__ import annotations

__all__ = ["P_FLOOR", "p_text"]

P_FLOOR = 1e-15
"""Below this a chi-square tail is rounding (and 0.0 where it underflows): printed as a bound."""


def p_text(p: float) -> str:
    """``"p = 0.0023"``, or ``"p < 1e-15"`` below :data:`P_FLOOR` (a tail that underflowed to 0
    read as "p = 0", an impossible certainty)."""
    return f"p < {P_FLOOR:g}" if p < P_FLOOR else f"p = {p:.2g}"
