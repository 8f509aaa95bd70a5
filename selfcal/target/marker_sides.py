"""The four sides of a detected marker: straight-line fits to their edge points, the corners'
noise predicted from the points' scatter, and the screening of sides that border something other
than the marker's own quiet zone (occluded markers).

Used by :func:`selfcal.target.aruco_detect.refine_corners_lines_batch`. Pixel units (OpenCV
convention); sides are indexed marker * 4 + k, side k running from corner k to corner k + 1.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "fit_lines",
    "corner_sigma",
    "side_levels",
    "side_level_spread",
    "sides_clean",
    "MAX_LEVEL_DROP",
    "MAX_SIDE_SPREAD",
]


def _masked_median(v: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Row-wise median of ``v`` (S, n) over ``valid`` entries (equals np.median of each row's
    valid entries; rows need at least one)."""
    srt = np.sort(np.where(valid, v, np.inf), axis=1)
    cnt = valid.sum(axis=1)
    rows = np.arange(len(v))
    return 0.5 * (srt[rows, (cnt - 1) // 2] + srt[rows, cnt // 2])


def fit_lines(
    P: np.ndarray, valid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Total-least-squares lines through the valid points of each row of ``P`` (S, n, 2), then
    twice: reject points beyond 3 MAD (+0.05 px) and refit. Returns unit normals (S, 2),
    offsets (S,) (``n . x = d``), a success mask (S,) (>= 4 points throughout) and the points
    kept by the last fit (S, n)."""
    ok = valid.sum(axis=1) >= 4
    keep = valid.copy()

    def tls(keep):
        w = keep.astype(float)
        cnt = np.maximum(w.sum(axis=1), 1.0)
        m = np.einsum("sn,snk->sk", w, P) / cnt[:, None]
        D = (P - m[:, None, :]) * w[..., None]
        sxx = np.einsum("sn,sn->s", D[..., 0], D[..., 0])
        syy = np.einsum("sn,sn->s", D[..., 1], D[..., 1])
        sxy = np.einsum("sn,sn->s", D[..., 0], D[..., 1])
        th = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # direction of the line (largest spread)
        n_line = np.stack([-np.sin(th), np.cos(th)], axis=1)
        return m, n_line

    for _ in range(2):
        m, n_line = tls(keep)
        res = np.einsum("snk,sk->sn", P - m[:, None, :], n_line)
        med = _masked_median(res, keep | ~ok[:, None])
        mad = 1.4826 * _masked_median(np.abs(res - med[:, None]), keep | ~ok[:, None])
        keep &= np.abs(res) <= 3.0 * mad[:, None] + 0.05
        ok &= keep.sum(axis=1) >= 4
    m, n_line = tls(keep)
    return n_line, np.einsum("sk,sk->s", n_line, m), ok, keep


def corner_sigma(
    P: np.ndarray, keep: np.ndarray, n_line: np.ndarray, corners: np.ndarray
) -> np.ndarray:
    """(n,) per-coordinate standard deviation (px, RMS over the four corners) of each marker's
    corners (n, 4, 2) predicted from the scatter of its sides' edge points about their fitted
    lines: a side of N kept points with residual variance ``s^2`` (dof N - 2) has normal-offset
    variance ``s^2 (1/N + u^2 / S_uu)`` at along-line position ``u`` from its centroid; the
    corner is the intersection of two sides (independent). ``P`` (4n, max_s, 2) edge points,
    ``keep`` (4n, max_s) those the fit kept (:func:`fit_lines`), ``n_line`` (n, 4, 2) the sides'
    unit normals."""
    w = keep.astype(float)
    cnt = w.sum(axis=1)
    m = np.einsum("sn,snk->sk", w, P) / np.maximum(cnt, 1.0)[:, None]
    nl = n_line.reshape(-1, 2)
    t = np.stack([nl[:, 1], -nl[:, 0]], axis=1)
    D = P - m[:, None, :]
    r = np.einsum("snk,sk->sn", D, nl) * w
    u = np.einsum("snk,sk->sn", D, t) * w
    s2 = (r**2).sum(axis=1) / np.maximum(cnt - 2.0, 1.0)
    suu = np.maximum((u**2).sum(axis=1), 1e-12)
    s2, suu, cnt = (a.reshape(-1, 4) for a in (s2, suu, cnt))
    m, t = m.reshape(-1, 4, 2), t.reshape(-1, 4, 2)

    def var_at(shift: int) -> np.ndarray:
        """(n, 4) normal-offset variance at each corner of side ``k - shift`` (corner k lies
        on sides k - 1 and k)."""
        mm, tt = np.roll(m, shift, axis=1), np.roll(t, shift, axis=1)
        uu = np.einsum("nck,nck->nc", corners - mm, tt)
        cc, ss = np.roll(cnt, shift, axis=1), np.roll(s2, shift, axis=1)
        return ss * (1.0 / np.maximum(cc, 1.0) + uu**2 / np.roll(suu, shift, axis=1))

    v1, v2 = var_at(1), var_at(0)
    n1, n2 = np.roll(n_line, 1, axis=1), n_line
    det = n1[..., 0] * n2[..., 1] - n1[..., 1] * n2[..., 0]
    det = np.where(np.abs(det) >= 1e-6, det, 1e-6)
    # A = [n1; n2], A^-1 = [[n2y, -n1y], [-n2x, n1x]] / det: trace(A^-1 diag(v) A^-T)
    tr = v1 * (n2[..., 0] ** 2 + n2[..., 1] ** 2) + v2 * (n1[..., 0] ** 2 + n1[..., 1] ** 2)
    return np.sqrt(np.mean(tr / det**2 / 2.0, axis=1))


MAX_LEVEL_DROP = 0.2
"""Largest drop of a side's quiet-zone (white) level, or rise of its black-border level, below
(above) the side's median, as a fraction of the side's median contrast, before the marker is
rejected as occluded or bordered by a foreign edge (measured on the rendered default scenario,
``python -m selfcal.studies.diagnose_render``: neighbouring raised supports that cover a corner raise
the affected side to 0.3-1; unoccluded sides stay below 0.05 without and 0.1 with 2 grey levels
of image noise)."""

MAX_SIDE_SPREAD = 0.1
"""Largest spread of a marker's sides' median quiet-zone (white) and black-border levels, as a
fraction of the marker's contrast (:func:`side_level_spread`), before the marker is rejected as
having a side bordered by a foreign surface along its whole length: a neighbouring raised
support in front of the quiet zone turns it grey next to the black border evenly along the side,
which :data:`MAX_LEVEL_DROP` (a level change *along* a side) cannot see, and the side's line fit
follows the support's silhouette (measured on the rendered default scenario,
``python -m selfcal.studies.diagnose_render``: such sides reach 0.14-0.37 with their corners 0.23-0.48 px
off; every other marker stays at or below 0.026 with and without 2 grey levels of image noise)."""


def side_levels(
    prof_side: np.ndarray,
    j: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    valid: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per side (S,): the median quiet-zone (white) and black-border levels of its profiles and
    the largest drop of a profile's white level / rise of its black level below (above) them.
    ``prof_side``/``j``: side and sample index of each profile; ``white``/``black``: its
    levels; ``valid`` (S, max_s) the profile slots."""
    S, max_s = valid.shape
    has = np.zeros((S, max_s), bool)
    has[prof_side, j] = True
    rows = has | ~np.any(has, axis=1, keepdims=True)
    w = np.zeros((S, max_s))
    w[prof_side, j] = white
    b = np.zeros((S, max_s))
    b[prof_side, j] = black
    w_med, b_med = _masked_median(w, rows), _masked_median(b, rows)
    drop = w_med - np.where(has, w, np.inf).min(axis=1)
    rise = np.where(has, b, -np.inf).max(axis=1) - b_med
    return w_med, b_med, drop, rise


def side_level_spread(w_med: np.ndarray, b_med: np.ndarray) -> np.ndarray:
    """(n, 4) how far each side's quiet-zone level lies below the marker's brightest side and
    its black level above the marker's darkest side, as a fraction of the marker's contrast
    (``w_med``/``b_med`` (n, 4): the sides' median levels); 0 for a marker whose four sides
    border the same white and the same black."""
    w_top = w_med.max(axis=1, keepdims=True)
    b_low = b_med.min(axis=1, keepdims=True)
    c = np.maximum(w_top - b_low, 1e-6)
    return np.maximum(w_top - w_med, b_med - b_low) / c


def sides_clean(
    prof_side: np.ndarray,
    j: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    valid: np.ndarray,
    n_s: np.ndarray,
) -> np.ndarray:
    """(n, 4) bool: every profile of each side had contrast (``valid`` (S, max_s)), the side's
    white and black levels stay within :data:`MAX_LEVEL_DROP` of their medians, and the side's
    median levels within :data:`MAX_SIDE_SPREAD` of the marker's other sides
    (:func:`side_level_spread`). ``prof_side``/``j``: side and sample index of each profile;
    ``white``/``black``: its levels; ``n_s`` (n, 4): profiles per side."""
    w_med, b_med, drop, rise = side_levels(prof_side, j, white, black, valid)
    c_med = np.maximum(w_med - b_med, 1e-6)
    full = valid.sum(axis=1) == n_s.ravel()
    own = (full & (drop / c_med <= MAX_LEVEL_DROP) & (rise / c_med <= MAX_LEVEL_DROP)).reshape(
        n_s.shape
    )
    spread = side_level_spread(w_med.reshape(n_s.shape), b_med.reshape(n_s.shape))
    return own & (spread <= MAX_SIDE_SPREAD)
