"""Exact collision check of the thin closed polyline over the whole cycle (MATH §11).

Segment i of a polyline ``V`` ``(6, 3)`` is ``[V_{i-1}, V_i]`` (vertex ``V_i`` on axis ``A_i``),
carried by link i; all coordinates are base coordinates at home (t = inf). For each of the nine
non-adjacent pairs (i, j), segment i stays fixed and segment j moves by the relative motion
``R_ij(t)`` (degree k <= 3). The lines meet exactly at the real roots of the reciprocal product
``Om(t) = l_A . m_B(t) + m_A . l_B(t)`` (degree <= 2k, plus t = inf where the degree drops); a
collision is a root where the clamped segment distance vanishes (parallel and collinear cases
included). ``Om ≡ 0`` (lines always meet) falls back to the exact minimum distance.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import poly
from paraloop_core.errors import RealizationError
from paraloop_core.realization.clearance import (
    MotionData,
    PairMotions,
    chart_roots,
    min_distance_batch,
    moved_line,
    plucker,
    segment_distance,
    segments_at,
    with_home,
)
from paraloop_core.tolerance import TOL

#: The nine segment pairs (i, j) that are not neighbours (MATH §11).
THIN_PAIRS = ((0, 2), (0, 3), (0, 4), (1, 3), (1, 4), (1, 5), (2, 4), (2, 5), (3, 5))
#: Batches larger than this are checked pair by pair (see :func:`colliding_polylines`).
_PER_PAIR_ABOVE = 24


def pair_collisions(
    md: MotionData, idx: np.ndarray, fixed: np.ndarray, moving: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Do fixed segments ``(B, 2, 3)`` and segments moved by ``md`` motions ``idx`` ``(B,)``
    ever meet for t in ``R u {inf}``? Returns ``(hit (B,), t_hit (B,))`` (``t_hit`` is the
    contact time with the smallest distance, NaN where there is no hit)."""
    n_items = len(idx)
    pa = plucker(fixed)
    la, ma = pa[:, :3], pa[:, 3:]

    def om_of(m: MotionData) -> np.ndarray:
        lb = moved_line(m, idx, moving)
        return np.einsum("bc,bcn->bn", la, lb[:, 3:]) + np.einsum("bc,bcn->bn", ma, lb[:, :3])

    om = om_of(md)
    # Om is bilinear in the two Plücker vectors: compare with the size of that product.
    lin = np.abs(md.lines).max(axis=(1, 2, 3))[idx]
    size = lin * np.linalg.norm(pa, axis=1) * np.linalg.norm(plucker(moving), axis=1)
    always = np.abs(om).max(axis=1) <= TOL.zero * size
    cand = with_home(chart_roots(  # in md's s
        md, lambda m: poly.real_poly_roots(om if m is md else om_of(m), rtol=TOL.zero).real))
    seg = segments_at(md, idx, moving, cand)
    dist = segment_distance(fixed[:, None, 0], fixed[:, None, 1], seg[..., 0, :], seg[..., 1, :])
    if np.any(always):  # rare: the lines meet for every t; use the exact minimum distance
        dmin, tmin = min_distance_batch(md, idx[always], fixed[always], moving[always])
        dist[always, 0], cand[always, 0] = dmin, md.to_s(tmin)
        dist[always, 1:] = np.inf
    length = np.linalg.norm(la, axis=1) + np.linalg.norm(moving[:, 1] - moving[:, 0], axis=1)
    best = np.argmin(dist, axis=1)
    rows = np.arange(n_items)
    hit = dist[rows, best] <= TOL.residual * length
    return hit, np.where(hit, md.to_t(cand[rows, best]), np.nan)


def thin_pair_motions(joint_factors: np.ndarray) -> list[tuple[MotionData, int]]:
    """Motion of ``R_ij`` for each of the nine :data:`THIN_PAIRS` as ``(data, index)``; pairs
    of one degree share one :class:`MotionData`."""
    return PairMotions(joint_factors, THIN_PAIRS).data(THIN_PAIRS)


def polyline_segments(polylines: np.ndarray) -> np.ndarray:
    """Segments ``(..., 6, 2, 3)`` of closed polylines ``(..., 6, 3)``: ``[V_{i-1}, V_i]``."""
    return np.stack([np.roll(polylines, 1, axis=-2), polylines], axis=-2)


def colliding_polylines(
    pair_motions: list[tuple[MotionData, int]], polylines: np.ndarray
) -> np.ndarray:
    """Mask ``(C,)``: polyline ``(C, 6, 3)`` collides somewhere on the cycle.

    ``pair_motions[p]`` is ``(data, index)`` of ``R_ij`` for ``THIN_PAIRS[p]``; pairs of one
    degree must share their data. Only still-free candidates go on to the next kernel call.
    """
    segs = polyline_segments(polylines)
    free = np.ones(len(polylines), dtype=bool)
    order = sorted(range(len(THIN_PAIRS)), key=lambda p: pair_motions[p][0].degree)
    # Many candidates: one pair per call, so colliding candidates drop out early. Few: all pairs
    # of one degree in one call (call overhead dominates). Low degree first either way.
    steps = [[p] for p in order] if len(polylines) > _PER_PAIR_ABOVE else [
        [p for p in order if pair_motions[p][0].degree == k]
        for k in sorted({md.degree for md, _ in pair_motions})]
    for group in steps:
        alive = np.flatnonzero(free)
        if alive.size == 0:
            break
        cand = np.repeat(alive, len(group))  # candidate-major, pairs of the group inner
        pairs = np.tile(group, alive.size)
        first = np.array([THIN_PAIRS[p][0] for p in pairs])
        second = np.array([THIN_PAIRS[p][1] for p in pairs])
        md = pair_motions[group[0]][0]
        index = np.array([pair_motions[p][1] for p in pairs])
        hit, _ = pair_collisions(md, index, segs[cand, first], segs[cand, second])
        free[alive[hit.reshape(alive.size, len(group)).any(axis=1)]] = False
    return ~free


def check_polylines(joint_factors: np.ndarray, polylines: np.ndarray) -> np.ndarray:
    """Public thin check: mask ``(...)`` of colliding closed polylines ``(..., 6, 3)`` (vertex
    ``V_i`` on axis ``A_i``, base frame at home) of the loop ``joint_factors`` ``(6, 8)``."""
    jf = np.asarray(joint_factors, dtype=np.float64)
    pl = np.asarray(polylines, dtype=np.float64)
    if jf.shape != (6, 8) or pl.shape[-2:] != (6, 3):
        raise RealizationError(
            f"need joint factors (6, 8) and polylines (..., 6, 3), got {jf.shape}, {pl.shape}",
            "bad-parameters",
        )
    if not (np.all(np.isfinite(jf)) and np.all(np.isfinite(pl))):
        raise RealizationError("joint factors and polylines must be finite", "bad-parameters")
    flat = pl.reshape(-1, 6, 3)
    return colliding_polylines(thin_pair_motions(jf), flat).reshape(pl.shape[:-2])
