"""Certified radii of a realization: how thick its links may be (issue 14).

The certificate proves a lower bound ``L`` (design units) of the distance over the whole cycle
between the centre lines of every pair of segments that must stay apart
(``Realization.pair_lower``, rows ``(edge, edge, link, link)``: even edges are bars ``S_iE_i``,
odd ones pins ``E_iS_{i+1}``). Capsules of radii ``r_a``, ``r_b`` about two such segments stay
apart if ``r_a + r_b <= L``. (Consecutive bars meet at their joint, where the joint hardware
separates the parts: not constrained here, see ``joint_lower`` and the fabrication sizing.) So

* the largest **uniform** radius of every segment (bars and pins) is ``min L / 2``;
* **per-bar** radii, the pins keeping the realization's radius ``rho``: the largest smallest
  bar radius first, then the largest sum (two small linear programs): each bar as thick as
  its neighbours over the cycle allow, with the same certificate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog


@dataclass(frozen=True)
class Radii:
    """``uniform`` (all segments alike) and ``per_bar`` ``(6,)`` (pins at ``pin``) radii,
    design units, each certified over the whole cycle by the realization's bounds."""

    uniform: float
    per_bar: np.ndarray
    pin: float


def certified_radii(pairs: np.ndarray, pair_lower: np.ndarray, rho: float) -> Radii:
    """:class:`Radii` from the certified rows ``pairs`` ``(N, 4)`` with bounds ``(N,)`` and
    the pin radius ``rho`` (the realization's, for which every bound is at least ``2 rho``)."""
    rows = np.asarray(pairs)[:, :2]
    low = np.asarray(pair_lower, float)
    if not np.all(np.isfinite(low)) or low.min() < 2 * rho * (1 - 1e-9):
        raise ValueError("the realization's bounds must be finite and at least 2 rho")
    bar = rows % 2 == 0
    a = np.zeros((len(rows), 6))
    for side in (0, 1):  # each bar of a row takes part of its bound
        a[np.flatnonzero(bar[:, side]), rows[bar[:, side], side] // 2] += 1.0
    b = low - rho * (~bar).sum(axis=1)  # pins keep rho
    keep = bar.any(axis=1)
    a, b = a[keep], b[keep]
    # 1) the largest t with every bar >= t; 2) the largest sum with every bar >= t
    a1 = np.hstack([a, np.zeros((len(a), 1))])
    floor = np.hstack([-np.eye(6), np.ones((6, 1))])  # t - r_i <= 0
    res = linprog(np.r_[np.zeros(6), -1.0], A_ub=np.vstack([a1, floor]),
                  b_ub=np.r_[b, np.zeros(6)], bounds=[(rho, None)] * 7, method="highs")
    t = res.x[-1] if res.success else rho
    res = linprog(-np.ones(6), A_ub=a, b_ub=b, bounds=[(t, None)] * 6, method="highs")
    per_bar = res.x if res.success else np.full(6, t)
    # the solver's round-off must not overstep a bound: shrink to the tightest row
    slack = np.max(np.where(a > 0, a * per_bar, 0).sum(axis=1) / np.maximum(b, 1e-300))
    per_bar = per_bar / max(1.0, float(slack))
    return Radii(float(low.min() / 2), per_bar, float(rho))


def radii_to_dict(r: Radii) -> dict:
    return {"uniform_max": r.uniform, "per_bar_max": r.per_bar.tolist(), "pin_radius": r.pin,
            "meaning": "largest radii certified over the whole cycle by the pair bounds: "
                       "'uniform_max' for every bar and pin alike, 'per_bar_max' for each bar "
                       "with the pins at 'pin_radius' (design units)"}
